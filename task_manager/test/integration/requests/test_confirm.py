"""system/confirm over real DDS: a task that waits for an operator's answer, alone and as a
mission step, and the answers /task_manager/confirm_task takes or refuses (issue 30, item 2)."""

from collections.abc import Iterator

import pytest
from test_msgs.action import Fibonacci

from task_manager.client import Subtask, TaskHandle, TaskManagerClient
from task_manager.core.names import CONFIRM
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.testing.gateway import wait_until
from task_manager.testing.harness import RosHarness
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer

TIMEOUT_SEC = 15.0


@pytest.fixture
def client() -> Iterator[TaskManagerClient]:
    with TaskManagerClient('test_confirm_client', timeout_sec=TIMEOUT_SEC) as client:
        yield client


@pytest.fixture
def photo(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> ScriptedActionServer:
    """A node with one task, `photo`, whose server this returns."""
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/photo')
    launch_task_manager({'photo': action_task('photo', f'{topic_prefix}/photo')})
    return server


def waiting(handle: TaskHandle) -> dict[str, object]:
    """The first feedback of a confirmation: it is waiting."""
    return next(feedback for feedback in handle.feedback(TIMEOUT_SEC))


def test_a_confirmation_waits_with_its_prompt_until_confirmed_and_keeps_who_confirmed(
    photo: ScriptedActionServer, client: TaskManagerClient
) -> None:
    handle = client.start_task(CONFIRM, {'prompt': 'Load the tray', 'timeout_sec': 60})
    feedback = waiting(handle)
    listed = wait_until(
        lambda: [t.status for t in client.active_tasks() if t.task_id == handle.task_id],
        'the confirmation in the active tasks',
    )

    answer = client.confirm(handle.task_id, comment='tray loaded', source='WEB:alice')
    result = handle.result(TIMEOUT_SEC)
    stored = client.task_states([handle.task_id])[0]

    assert feedback['prompt'] == 'Load the tray'
    assert 0 < float(str(feedback['remaining_sec'])) <= 60
    assert listed == [TaskStatus.IN_PROGRESS]
    assert (answer.taken, answer.error_code, answer.message) == (True, '', '')
    expected = {
        'confirmed': True,
        'by': 'WEB:alice',
        'comment': 'tray loaded',
        'outcome': 'confirmed',
    }
    assert (result.status, result.error_code, result.result) == (
        TaskStatus.DONE,
        ErrorCode.NONE,
        expected,
    )
    assert (stored.status, stored.result) == (TaskStatus.DONE, expected)  # in the history


def test_a_rejected_confirmation_ends_error_and_takes_no_other_answer(
    photo: ScriptedActionServer, client: TaskManagerClient
) -> None:
    handle = client.start_task(CONFIRM, {'prompt': 'Is the path clear?'}, task_id='clear')
    waiting(handle)

    rejected = client.confirm('clear', reject=True, comment='a box is in the way', source='ops')
    result = handle.result(TIMEOUT_SEC)
    again = client.confirm('clear', reject=True, comment='a box is in the way', source='ops')
    late = client.confirm('clear', source='taskctl')

    assert rejected.taken
    assert (result.status, result.error_code) == (TaskStatus.ERROR, ErrorCode.REJECTED)
    assert result.result == {
        'confirmed': False,
        'by': 'ops',
        'comment': 'a box is in the way',
        'outcome': 'rejected',
    }
    assert again.taken  # the same answer asked again (its reply lost) is the one it took
    assert (late.taken, late.error_code) == (False, 'not_waiting')
    assert late.message == "task 'clear' (system/confirm) has ended ERROR; it takes no more answers"


def test_without_an_answer_it_fails_or_continues_as_on_timeout_says(
    photo: ScriptedActionServer, client: TaskManagerClient
) -> None:
    fails = client.start_task(CONFIRM, {'prompt': 'Go?', 'timeout_sec': 0.5})
    goes_on = client.start_task(
        CONFIRM, {'prompt': 'Go?', 'timeout_sec': 0.5, 'on_timeout': 'continue'}
    )

    failed = fails.result(TIMEOUT_SEC)
    continued = goes_on.result(TIMEOUT_SEC)

    unanswered = {'confirmed': False, 'by': '', 'comment': '', 'outcome': 'timed_out'}
    assert (failed.status, failed.error_code, failed.result) == (
        TaskStatus.ERROR,
        ErrorCode.TIMEOUT,
        unanswered,
    )
    assert (continued.status, continued.error_code, continued.result) == (
        TaskStatus.DONE,
        ErrorCode.NONE,
        unanswered,
    )


def test_several_confirmations_wait_at_once_and_each_takes_its_own_answer(
    photo: ScriptedActionServer, client: TaskManagerClient
) -> None:
    handles = [client.start_task(CONFIRM, {'prompt': f'step {i}?'}) for i in range(3)]
    for handle in handles:
        waiting(handle)

    client.confirm(handles[1].task_id, source='taskctl')
    second = handles[1].result(TIMEOUT_SEC)
    still_waiting = [handles[0].done(), handles[2].done()]
    client.confirm(handles[0].task_id, reject=True, source='taskctl')
    client.confirm(handles[2].task_id, source='taskctl')

    assert second.status is TaskStatus.DONE
    assert still_waiting == [False, False]
    assert [h.result(TIMEOUT_SEC).status for h in handles] == [
        TaskStatus.ERROR,
        TaskStatus.DONE,
        TaskStatus.DONE,
    ]


def test_a_mission_waits_at_its_confirm_step_until_confirmed_then_goes_on(
    photo: ScriptedActionServer, client: TaskManagerClient
) -> None:
    mission, (confirm_id, photo_id) = client.start_mission(
        [Subtask(CONFIRM, {'prompt': 'Load the tray'}), Subtask('photo', {'order': 3})]
    )
    waiting(mission.subtasks[0])
    started_before_the_answer = [h.task_id for h in mission.subtasks if h.state is not None]

    client.confirm(confirm_id, source='WEB:bob')
    goal = photo.wait_for_goals(1, TIMEOUT_SEC)[0]
    goal.succeed(Fibonacci.Result(sequence=[3]))
    result = mission.result(TIMEOUT_SEC)
    step = client.task_states([confirm_id])[0]

    assert started_before_the_answer == [confirm_id]  # the photo waited for the answer
    assert result.status is TaskStatus.DONE
    assert (step.status, step.mission_id, step.result) == (
        TaskStatus.DONE,
        mission.task_id,
        {'confirmed': True, 'by': 'WEB:bob', 'comment': '', 'outcome': 'confirmed'},
    )
    assert client.task_states([photo_id])[0].status is TaskStatus.DONE


@pytest.mark.parametrize('allow_skipping', [False, True])
def test_a_rejected_step_fails_the_mission_unless_it_may_be_skipped(
    photo: ScriptedActionServer, client: TaskManagerClient, allow_skipping: bool
) -> None:
    step = Subtask(CONFIRM, {'prompt': 'Load the tray'}, allow_skipping=allow_skipping)
    mission, (confirm_id, _) = client.start_mission([step, Subtask('photo', {'order': 1})])
    waiting(mission.subtasks[0])

    client.confirm(confirm_id, reject=True, source='taskctl')
    if allow_skipping:
        photo.wait_for_goals(1, TIMEOUT_SEC)[0].succeed(Fibonacci.Result())
    result = mission.result(TIMEOUT_SEC)

    assert mission.subtasks[0].result(TIMEOUT_SEC).error_code is ErrorCode.REJECTED
    assert result.status is (TaskStatus.DONE if allow_skipping else TaskStatus.ERROR)
    assert mission.subtasks[1].done() is allow_skipping  # a failed mission never started it


def test_a_waiting_confirmation_is_cancelled_by_its_client_and_by_stop(
    photo: ScriptedActionServer, client: TaskManagerClient
) -> None:
    cancelled = client.start_task(CONFIRM, {'prompt': 'Go?'})
    stopped = client.start_task(CONFIRM, {'prompt': 'Go?'})
    waiting(cancelled)
    waiting(stopped)

    assert cancelled.cancel()
    assert cancelled.result(TIMEOUT_SEC).status is TaskStatus.CANCELED
    assert not stopped.done()
    client.stop(source='taskctl')
    assert stopped.result(TIMEOUT_SEC).status is TaskStatus.CANCELED


def test_an_answer_to_a_task_that_is_no_waiting_confirmation_says_precisely_why(
    photo: ScriptedActionServer, client: TaskManagerClient
) -> None:
    running = client.start_task('photo', {'order': 1}, task_id='snap')
    photo.wait_for_goals(1, TIMEOUT_SEC)
    wait_until(lambda: running.state and running.state.status is TaskStatus.IN_PROGRESS, 'snap')
    confirm = client.start_task(CONFIRM, {'prompt': 'Go?'}, task_id='go')
    waiting(confirm)

    unknown = client.confirm('ghost', source='taskctl')
    not_a_confirm = client.confirm('snap', source='taskctl')
    bad_comment = client.confirm('go', comment='line\nforged', source='taskctl')
    no_source = client.confirm('go', source='')

    assert (unknown.taken, unknown.error_code, unknown.message) == (
        False,
        'not_found',
        "no task 'ghost': none is active, and none is in the history",
    )
    assert (not_a_confirm.taken, not_a_confirm.error_code, not_a_confirm.message) == (
        False,
        'not_waiting',
        "task 'snap' is a photo task, not system/confirm; only a waiting system/confirm takes "
        'an answer',
    )
    assert (bad_comment.error_code, bad_comment.taken) == ('invalid_request', False)
    assert 'comment contains the character U+000A at position 4' in bad_comment.message
    assert (no_source.error_code, no_source.taken) == ('invalid_request', False)
    assert not confirm.done()  # refused answers leave it waiting
    client.confirm('go', source='taskctl')
    assert confirm.result(TIMEOUT_SEC).status is TaskStatus.DONE


@pytest.mark.parametrize(
    ('task_data', 'words'),
    [
        ({'timeout_sec': 5}, "field 'prompt': is required"),
        ({'prompt': 'Go?', 'timeout_sec': -1}, "field 'timeout_sec': must be a number"),
        ({'prompt': 'Go?', 'on_timeout': 'skip'}, "field 'on_timeout': must be one of"),
    ],
)
def test_a_wrong_goal_ends_error_naming_its_field(
    photo: ScriptedActionServer,
    client: TaskManagerClient,
    task_data: dict[str, object],
    words: str,
) -> None:
    result = client.run_task(CONFIRM, task_data, timeout_sec=TIMEOUT_SEC)

    assert (result.status, result.error_code) == (
        TaskStatus.ERROR,
        ErrorCode.TASK_DATA_PARSING_FAILED,
    )
    assert words in result.result['error']
