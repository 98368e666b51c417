"""The Python client's feedback, stamps and task states, over real DDS against a real node."""

import threading
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
from task_manager_msgs.msg import TaskEvent as TaskEventMessage
from task_manager_msgs.msg import TaskEventArray
from test_msgs.action import Fibonacci

from task_manager.client import (
    Subtask,
    TaskEventKind,
    TaskManagerClient,
    TaskResult,
    TaskState,
)
from task_manager.core.names import TASK_EVENT_BATCHES_TOPIC, TASK_EVENTS_TOPIC
from task_manager.core.status import TaskStatus
from task_manager.rclpy_tools import qos
from task_manager.testing.gateway import wait_until
from task_manager.testing.harness import RosHarness
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import (
    ScriptedActionServer,
    ScriptedGoal,
    publish_feedback_until,
)

TIMEOUT_SEC = 15.0
BURST = 500
BURST_TIMEOUT_SEC = 60.0
# The burst's server shares this process with the client and two recorders of every event: on a
# loaded machine (more test processes than cores) its answer to a goal can take over the
# default 5 s, which is not what the test is about.
BURST_GOAL_RESPONSE_TIMEOUT_SEC = 30.0


class FeedbackLog:
    """A feedback callback; the test waits on what it got."""

    def __init__(self) -> None:
        self.received: list[dict[str, Any]] = []
        self._changed = threading.Condition()

    def __call__(self, feedback: dict[str, Any]) -> None:
        with self._changed:
            self.received.append(feedback)
            self._changed.notify_all()

    def has(self, feedback: dict[str, Any], timeout_sec: float) -> bool:
        with self._changed:
            return self._changed.wait_for(lambda: feedback in self.received, timeout_sec)


def _launch(
    ros: RosHarness, launch: LaunchTaskManager, prefix: str, **parameters: Any
) -> ScriptedActionServer:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/fib')
    launch({'fib': action_task('fib', f'{prefix}/fib', reentrant=True)}, **parameters)
    return server


@pytest.fixture
def client() -> Iterator[TaskManagerClient]:
    with TaskManagerClient('test_client', timeout_sec=TIMEOUT_SEC) as client:
        yield client


def _stamps(record: TaskResult | TaskState) -> tuple[datetime, datetime, datetime]:
    """(received, started, ended): in that order, timezone-aware, of the last minutes."""
    received, started, ended = record.received_at, record.started_at, record.ended_at
    assert received is not None and started is not None and ended is not None
    assert received <= started <= ended
    assert ended.tzinfo is not None
    assert abs(datetime.now(UTC) - ended) < timedelta(minutes=5)
    return received, started, ended


def test_a_handle_gets_its_feedback_by_callback_and_iterator_and_a_stamped_result(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    server = _launch(ros, launch_task_manager, topic_prefix)
    client.wait_until_available()
    handle = client.start_task('fib', {'order': 3}, task_id='fed')
    log = FeedbackLog()

    def broken(_: dict[str, Any]) -> None:
        raise RuntimeError('a callback bug')

    handle.on_feedback(broken)  # logged; the others still get every update
    handle.on_feedback(log)
    goal: ScriptedGoal = server.wait_for_goals(1, TIMEOUT_SEC)[0]
    first = {'sequence': [0, 1]}
    publish_feedback_until(
        goal, Fibonacci.Feedback(sequence=[0, 1]), lambda t: log.has(first, t), TIMEOUT_SEC
    )
    updates = handle.feedback(timeout_sec=TIMEOUT_SEC)
    latest = next(updates)  # the latest already received comes first
    goal.publish_feedback(Fibonacci.Feedback(sequence=[0, 1, 1]))  # discovery is done: once
    second = next(f for f in updates if f != first)  # the first may have been sent twice
    goal.succeed(Fibonacci.Result(sequence=[0, 1, 1, 2]))
    rest = list(updates)  # ends with the task
    result = handle.result(TIMEOUT_SEC)

    assert (latest, second, rest) == (first, {'sequence': [0, 1, 1]}, [])
    assert log.has({'sequence': [0, 1, 1]}, TIMEOUT_SEC)
    assert (result.status, result.result) == (TaskStatus.DONE, {'sequence': [0, 1, 1, 2]})
    _, started, ended = _stamps(result)
    assert result.duration == ended - started
    assert handle.state is not None and handle.state.status is TaskStatus.DONE
    assert handle.latest_feedback == {'sequence': [0, 1, 1]}


def test_task_states_events_and_kept_results_carry_datetimes(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    server = _launch(ros, launch_task_manager, topic_prefix)
    client.wait_until_available(events=True)
    assert client.events_connected
    handle = client.start_task('fib', {'order': 4}, task_id='stamped', source='UI')
    log = FeedbackLog()
    handle.on_feedback(log)
    goal = server.wait_for_goals(1, TIMEOUT_SEC)[0]
    feedback = Fibonacci.Feedback(sequence=[5])
    publish_feedback_until(goal, feedback, lambda t: log.has({'sequence': [5]}, t), TIMEOUT_SEC)
    active = client.task_states()
    unknown = client.task_states(['no-such-id'])
    events = client.task_events(timeout_sec=TIMEOUT_SEC, until=handle.result_future)
    goal.succeed(Fibonacci.Result(sequence=[3]))
    ended = [e for e in events if e.kind is TaskEventKind.ENDED]
    handle.result(TIMEOUT_SEC)
    kept = next(r for r in client.recent_results() if r.task_id == 'stamped')
    (state,) = client.task_states(['stamped'])

    (running,) = [s for s in active if s.task_id == 'stamped']
    assert (running.status, running.source, running.feedback) == (
        TaskStatus.IN_PROGRESS,
        'UI',
        {'sequence': [5]},
    )
    assert running.started_at is not None and running.ended_at is None
    elapsed = running.elapsed()
    assert elapsed is not None and timedelta(0) <= elapsed < timedelta(minutes=5)
    assert unknown == []
    assert [e.task.to_result().result for e in ended] == [{'sequence': [3]}]
    for stamped in (ended[0].task, kept, state):
        _stamps(stamped)
    assert kept.ended_at == state.ended_at == ended[0].task.ended_at
    assert ended[0].stamp >= _stamps(ended[0].task)[2]


def test_a_missions_subtasks_have_handles_and_its_progress_is_its_feedback(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    server = _launch(ros, launch_task_manager, topic_prefix)
    client.wait_until_available()
    mission, ids = client.start_mission(
        [Subtask('fib', {'order': 1}, task_id='one'), Subtask('fib', {'order': 2}, task_id='two')]
    )
    progress = mission.feedback(timeout_sec=TIMEOUT_SEC)
    server.wait_for_goals(1, TIMEOUT_SEC)[0].succeed(Fibonacci.Result(sequence=[1]))
    server.wait_for_goals(2, TIMEOUT_SEC)[1].succeed(Fibonacci.Result(sequence=[1, 1]))
    rows = list(progress)
    result = mission.result(TIMEOUT_SEC)
    first, second = (s.result(TIMEOUT_SEC) for s in mission.subtasks)

    assert ids == ['one', 'two'] == [s.task_id for s in mission.subtasks]
    assert result.ok
    assert rows and rows[-1]['current_index'] == -1
    assert [(r['task_id'], r['task_status']) for r in rows[-1]['subtasks']] == [
        ('one', 'DONE'),
        ('two', 'DONE'),
    ]
    assert (first.result, second.result) == ({'sequence': [1]}, {'sequence': [1, 1]})
    assert _stamps(first)[2] <= _stamps(second)[1]
    assert mission.subtasks[0].state is not None
    assert mission.subtasks[0].state.mission_id == mission.task_id


def test_without_the_event_stream_results_have_no_stamps_and_feedback_ends_with_the_task(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    server = _launch(ros, launch_task_manager, topic_prefix, publish_task_events=False)
    client.wait_until_available(events=True)
    handle = client.start_task('fib', {'order': 1})
    server.wait_for_goals(1, TIMEOUT_SEC)[0].succeed(Fibonacci.Result(sequence=[1]))

    feedback = list(handle.feedback(timeout_sec=TIMEOUT_SEC))
    result = handle.result(TIMEOUT_SEC)

    assert not client.events_connected
    assert feedback == [] and handle.state is None
    assert result.ok and (result.started_at, result.ended_at, result.duration) == (None, None, None)


def test_recent_results_stamp_only_the_newest_task_of_an_id_used_again(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    server = _launch(ros, launch_task_manager, topic_prefix)
    client.wait_until_available()
    first = client.start_task('fib', {'order': 1}, task_id='again')
    server.wait_for_goals(1, TIMEOUT_SEC)[0].succeed(Fibonacci.Result(sequence=[1]))
    first.result(TIMEOUT_SEC)
    second = client.start_task('fib', {'order': 2}, task_id='again')
    server.wait_for_goals(2, TIMEOUT_SEC)[1].succeed(Fibonacci.Result(sequence=[2]))
    newest = second.result(TIMEOUT_SEC)

    older, newer = [r for r in client.recent_results() if r.task_id == 'again']

    assert (older.result, older.ended_at) == ({'sequence': [1]}, None)
    assert newer.result == {'sequence': [2]} and newer.ended_at == newest.ended_at


def test_every_event_of_500_tasks_at_once_reaches_the_client_in_order_in_fewer_messages(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    """The node publishes a turn's events as one TaskEventArray on
    /task_manager/task_event_batches, which the client follows: of 500 tasks started at once,
    each has RECEIVED, STARTED and ENDED, in that order, the same events in the same order as
    /task_manager/task_events carries one by one, in fewer messages than events; no batch is
    said to be lost."""
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib', on_goal=lambda g: g.succeed())
    launch_task_manager(
        {
            'fib': action_task(
                'fib',
                f'{topic_prefix}/fib',
                reentrant=True,
                goal_response_timeout=BURST_GOAL_RESPONSE_TIMEOUT_SEC,
            )
        }
    )
    one_by_one = ros.record(TaskEventMessage, TASK_EVENTS_TOPIC, qos.TASK_EVENTS)
    batches = ros.record(TaskEventArray, TASK_EVENT_BATCHES_TOPIC, qos.TASK_EVENTS)
    client.wait_until_available(events=True)
    client.start_task('fib', {'order': 1}, task_id='first').result(TIMEOUT_SEC)
    for recorder in (one_by_one, batches):  # both reach the node: it publishes on both
        recorder.wait_until(lambda messages: len(messages) > 0, TIMEOUT_SEC, 'the first events')
    events_before = len(one_by_one.snapshot())
    batches_before = len(batches.snapshot())
    received: list[tuple[str, str]] = []
    client.on_task_event(lambda event: received.append((event.task.task_id, str(event.kind))))
    lost: list[int] = []
    client.on_events_lost(lost.append)
    ids = [f'burst-{index:03d}' for index in range(BURST)]

    handles = [client.start_task('fib', {'order': 1}, task_id=task_id) for task_id in ids]
    statuses = [handle.result(BURST_TIMEOUT_SEC).status for handle in handles]
    one_by_one.wait_until(
        lambda messages: (
            sum(m.task.task_id != 'first' for m in messages[events_before:]) >= 3 * BURST
        ),
        TIMEOUT_SEC,
        'every event',
    )
    batches.wait_until(
        lambda messages: (
            sum(
                event.task.task_id != 'first'
                for m in messages[batches_before:]
                for event in m.events
            )
            >= 3 * BURST
        ),
        TIMEOUT_SEC,
        'every batched event',
    )
    batched = [
        (event.task.task_id, event.event)
        for batch in batches.snapshot()[batches_before:]
        for event in batch.events
        if event.task.task_id != 'first'
    ]
    published = [
        (m.task.task_id, m.event)
        for m in one_by_one.snapshot()[events_before:]
        if m.task.task_id != 'first'
    ]
    # the client's own subscription is a third reader: it may be behind the two recorders
    wait_until(
        lambda: sum(pair[0] != 'first' for pair in received) >= len(published),
        'the client has every event',
        TIMEOUT_SEC,
    )

    assert statuses == [TaskStatus.DONE] * BURST
    for task_id in ids:
        assert [kind for mine, kind in received if mine == task_id] == [
            'RECEIVED',
            'STARTED',
            'ENDED',
        ], task_id
    assert batched == published
    assert [pair for pair in received if pair[0] != 'first'] == published
    assert len(batches.snapshot()) - batches_before < len(published)
    assert len(published) == 3 * BURST
    assert lost == []  # none missing, none said to be


class ListLog:
    """Collects what an active_task_updates iterator yields, from a thread of its own."""

    def __init__(self, client: TaskManagerClient) -> None:
        self.lists: list[list[tuple[str, TaskStatus]]] = []
        self._changed = threading.Condition()
        self._client = client
        self._thread = threading.Thread(target=self._watch, daemon=True)
        self._thread.start()

    def _watch(self) -> None:
        for update in self._client.active_task_updates(timeout_sec=TIMEOUT_SEC):
            with self._changed:
                self.lists.append([(t.task_id, t.status) for t in update])
                self._changed.notify_all()

    def wait_for(self, entry: tuple[str, TaskStatus], timeout_sec: float = TIMEOUT_SEC) -> bool:
        with self._changed:
            return self._changed.wait_for(
                lambda: any(entry in listed for listed in self.lists), timeout_sec
            )

    def wait_until_following(self, tm: Any, attempts: int = 10) -> None:
        """Run short tasks until one reaches the log (its iterator follows from its first
        next(), in its thread: a task run before that is not for it)."""
        for attempt in range(attempts):
            task_id = f'listening-{attempt}'
            tm.run('fib', {'order': 1}, task_id=task_id)
            if self.wait_for((task_id, TaskStatus.IN_PROGRESS), TIMEOUT_SEC / attempts):
                return
        raise AssertionError(f'the log got no task of {attempts}: {self.lists}')


def test_a_listener_gets_every_active_list_even_when_the_client_is_held_up(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    """A task that starts and ends while the client's executor is busy still reaches
    active_task_updates as IN_PROGRESS: of the lists published meanwhile, the newest alone (what
    active_tasks() needs) would show only the empty list."""
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib', on_goal=lambda g: g.succeed())
    tm = launch_task_manager({'fib': action_task('fib', f'{topic_prefix}/fib', reentrant=True)})
    client.wait_until_available(events=True)
    released = threading.Event()
    held = threading.Event()

    def hold_the_executor(event: Any) -> None:
        if event.task.task_id == 'hold':
            held.set()
            released.wait(TIMEOUT_SEC)

    client.on_task_event(hold_the_executor)
    log = ListLog(client)
    log.wait_until_following(tm)
    try:
        tm.run('fib', {'order': 1}, task_id='hold')
        assert held.wait(TIMEOUT_SEC), 'the client never got the events of hold'
        assert tm.run('fib', {'order': 1}, task_id='quick').task_status == 'DONE'
        tm.active.wait_until(
            lambda messages: bool(messages) and not messages[-1].active_tasks, TIMEOUT_SEC
        )
    finally:
        released.set()

    assert log.wait_for(('quick', TaskStatus.IN_PROGRESS)), log.lists


def test_a_listener_that_starts_late_gets_no_list_that_was_over(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    """The reader of every list is transient local (a list published while the node's writer
    still learns of it comes as history); the history from before the first next() is not
    yielded: the first lists are those of the next change."""
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib', on_goal=lambda g: g.succeed())
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/hold')
    tm = launch_task_manager(
        {
            'fib': action_task('fib', f'{topic_prefix}/fib', reentrant=True),
            'hold': action_task('hold', f'{topic_prefix}/hold'),
        }
    )
    client.wait_until_available()
    for task_id in ('over-1', 'over-2', 'over-3'):
        assert tm.run('fib', {'order': 1}, task_id=task_id).task_status == 'DONE'
    tm.send('hold', {'order': 1}, task_id='stays')
    assert wait_until(
        lambda: [t.task_id for t in client.active_tasks()] == ['stays'],
        'the latest list, with the held task only',
    )
    log = ListLog(client)
    log.wait_until_following(tm)
    seen = {task_id for listed in log.lists for task_id, _ in listed}
    assert 'stays' in seen and not seen & {'over-1', 'over-2', 'over-3'}, log.lists


def test_the_latest_active_list_is_read_only_when_asked_for(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    """The client keeps the newest list as its bytes: a client that never asks for it (a
    gateway follows the events) converts no list into Python; active_tasks() reads it."""
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/hold')
    tm = launch_task_manager({'hold': action_task('hold', f'{topic_prefix}/hold')})
    client.wait_until_available()
    tm.send('hold', {'order': 1}, task_id='held')
    tm.wait_in_progress('held')
    active = client._active
    assert wait_until(
        lambda: (
            b'held' in (active._latest_bytes or b'')
            and b'IN_PROGRESS' in (active._latest_bytes or b'')
        ),
        'the list with the held task in progress',
    )
    assert active._latest is None  # not read yet
    listed = [(t.task_id, t.status) for t in client.active_tasks()]
    assert listed == [('held', TaskStatus.IN_PROGRESS)]
    assert active._latest is not None  # read once, kept until the next list
