"""The Python client's side of deciding what runs (issue 29): request options through
StartTask, reprioritize, why, and the new fields of a task's state, against a real node;
and messages of a newer Task Manager that must not stop the client."""

import threading
from collections.abc import Iterator
from typing import Any

import pytest
from task_manager_msgs.msg import ActiveTask, ActiveTaskArray, TaskEventArray
from task_manager_msgs.msg import TaskEvent as TaskEventMessage
from task_manager_msgs.msg import TaskState as TaskStateMessage
from test_msgs.action import Fibonacci

from task_manager.client import Subtask, TaskEvent, TaskEventKind, TaskManagerClient
from task_manager.core.errors import TaskManagerError
from task_manager.core.names import (
    ACTIVE_TASKS_TOPIC,
    EXECUTE_TASK_ACTION,
    START_TASK_ACTION,
    TASK_EVENT_BATCHES_TOPIC,
)
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.rclpy_tools import qos
from task_manager.rclpy_tools.action_services import action_service_name
from task_manager.testing.gateway import wait_until
from task_manager.testing.harness import RosHarness
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer

TIMEOUT_SEC = 15.0


@pytest.fixture
def client() -> Iterator[TaskManagerClient]:
    with TaskManagerClient('test_client', timeout_sec=TIMEOUT_SEC) as client:
        yield client


def robot(
    ros: RosHarness, launch: LaunchTaskManager, prefix: str
) -> tuple[TaskManagerProbe, dict[str, ScriptedActionServer]]:
    """A node with a drive and a dock that both hold `base`."""
    tasks = {
        name: action_task(name, f'{prefix}/{name}', resources=['base'])
        for name in ('drive', 'dock')
    }
    servers = {
        name: ScriptedActionServer(ros.node, Fibonacci, entry['topic'])
        for name, entry in tasks.items()
    }
    return launch(tasks), servers


class EventLog:
    """A client's on_task_event callback; the test waits on what it got."""

    def __init__(self) -> None:
        self.events: list[TaskEvent] = []
        self._changed = threading.Condition()

    def __call__(self, event: TaskEvent) -> None:
        with self._changed:
            self.events.append(event)
            self._changed.notify_all()

    def wait_for(self, task_id: str, kind: TaskEventKind) -> TaskEvent:
        def found() -> TaskEvent | None:
            return next(
                (e for e in self.events if e.task.task_id == task_id and e.kind is kind), None
            )

        with self._changed:
            assert self._changed.wait_for(lambda: found() is not None, TIMEOUT_SEC), (
                f'no {kind} event of {task_id}'
            )
            event = found()
            assert event is not None
            return event


def test_a_request_without_options_goes_through_execute_task_as_ever(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    _, servers = robot(ros, launch_task_manager, topic_prefix)
    client.wait_until_available()

    handle = client.start_task('drive', {'order': 1}, task_id='plain')
    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()

    assert handle.result(TIMEOUT_SEC).status is TaskStatus.DONE
    send_goal = action_service_name(START_TASK_ACTION, 'send_goal')
    assert ros.node.count_clients(send_goal) == 0  # the StartTask client is made on first use
    assert ros.node.count_clients(action_service_name(EXECUTE_TASK_ACTION, 'send_goal')) >= 1
    assert client.why('plain') == []


def test_a_queued_request_is_listed_with_its_place_and_priority_and_says_why(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    client.wait_until_available(events=True)
    log = EventLog()
    client.on_task_event(log)
    drive = client.start_task('drive', {'order': 1}, task_id='drive-1', priority=5)
    tm.wait_in_progress('drive-1')

    dock = client.start_task('dock', {'order': 1}, task_id='dock-1', on_conflict='queue')

    queued = log.wait_for('dock-1', TaskEventKind.QUEUED)
    assert queued.reason == 'queued behind drive-1 (priority 5), which holds base'
    (state,) = client.task_states(['dock-1'])
    assert (state.status, state.queue_position, state.priority) == (TaskStatus.QUEUED, 1, 0)
    assert client.task_states(['drive-1'])[0].priority == 5
    (decision,) = client.why('dock-1')
    assert (decision.decision, decision.reason) == ('queued', queued.reason)
    assert decision.at.tzinfo is not None
    assert ('dock-1', TaskStatus.QUEUED) in {(t.task_id, t.status) for t in client.active_tasks()}

    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    servers['dock'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    assert drive.result(TIMEOUT_SEC).ok and dock.result(TIMEOUT_SEC).ok
    assert [d.decision for d in client.why('dock-1')] == ['queued', 'started']
    assert dock.state is not None and dock.state.attempt == 1


def test_a_lower_priority_is_refused_and_why_names_the_drive_its_priority_and_base(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    client.wait_until_available()
    client.start_task('drive', {'order': 1}, task_id='drive-12', priority=5)
    tm.wait_in_progress('drive-12')

    refused = client.run_task('dock', {'order': 1}, task_id='dock-3', priority=1)

    assert (refused.status, refused.error_code) == (TaskStatus.ERROR, ErrorCode.PREEMPTION_REFUSED)
    (decision,) = client.why('dock-3')
    assert decision.decision == 'refused'
    assert decision.reason == "refused: priority 1 is below drive-12's 5, which holds base"
    assert client.run_task(
        'dock', {'order': 1}, task_id='dock-4', on_conflict='REJECT'
    ).error_code is (ErrorCode.RESOURCE_BUSY)
    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()


def test_reprioritize_moves_a_queued_task_up(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    client.wait_until_available()
    client.start_task('drive', {'order': 1}, task_id='drive-1')
    tm.wait_in_progress('drive-1')
    client.start_task('dock', {'order': 1}, task_id='first', on_conflict='queue')
    second = client.start_task('dock', {'order': 2}, task_id='second', on_conflict='queue')
    tm.wait_active(lambda t: ('second', 'QUEUED') in t)

    changed = client.reprioritize(['second', 'ghost'], 3)

    assert changed.status is TaskStatus.ERROR  # one of the two ids is no active task
    assert changed.result['successful_changes'] == ['second']
    assert len(changed.result['errors']) == 1 and 'ghost' in changed.result['errors'][0]
    (state,) = client.task_states(['second'])
    assert (state.priority, state.queue_position) == (3, 1)
    assert client.why('second')[-1].decision == 'reprioritized'
    assert client.reprioritize(['second'], 4).ok
    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    tm.wait_in_progress('second')
    second.cancel()
    assert second.result(TIMEOUT_SEC).status is TaskStatus.CANCELED


def test_the_timeouts_of_a_request_end_it_error_timeout(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    client.wait_until_available()

    timed_out = client.run_task('drive', {'order': 1}, task_id='drive-1', task_timeout_sec=0.5)

    assert (timed_out.status, timed_out.error_code) == (TaskStatus.ERROR, ErrorCode.TIMEOUT)
    assert servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()
    assert client.why('drive-1')[-1].decision == 'timeout'
    client.start_task('drive', {'order': 1}, task_id='drive-2')
    tm.wait_in_progress('drive-2')
    never_started = client.run_task(
        'dock', {'order': 1}, task_id='dock-1', on_conflict='queue', queue_timeout_sec=0.3
    )
    assert never_started.error_code is ErrorCode.TIMEOUT
    assert 'in the queue' in never_started.error_message
    servers['drive'].wait_for_goals(2, TIMEOUT_SEC)[1].succeed()


def test_a_mission_is_started_with_its_options(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    client.wait_until_available()
    client.start_task('drive', {'order': 1}, task_id='drive-1', priority=2)
    tm.wait_in_progress('drive-1')

    mission, _ = client.start_mission(
        [Subtask('dock', '{"order": 1}', task_id='dock-1')], task_id='tour', priority=7
    )

    tm.wait_in_progress('dock-1')
    assert client.task_states(['tour'])[0].priority == 7
    assert client.why('drive-1')[-1].decision == 'preempted'
    servers['dock'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    assert mission.result(TIMEOUT_SEC).ok


@pytest.mark.parametrize(
    ('options', 'words'),
    [
        ({'priority': 2**31}, 'priority must be from'),
        ({'priority': 1.5}, 'priority must be an integer'),
        ({'on_conflict': 'wait'}, 'on_conflict must be one of preempt, queue, reject'),
        ({'timeout_sec': 0}, 'timeout_sec must be a finite number of seconds > 0'),
        ({'queue_timeout_sec': float('inf')}, 'queue_timeout_sec must be a finite'),
        ({'feedback_timeout_sec': -1}, 'feedback_timeout_sec must be a finite'),
    ],
)
def test_unusable_options_are_refused_before_anything_is_sent(
    client: TaskManagerClient, options: dict[str, Any], words: str
) -> None:
    with pytest.raises(ValueError, match=words):
        client.start_task('drive', **options)
    with pytest.raises(ValueError, match='priority must be'):
        client.reprioritize(['x'], 2**40)


def test_why_of_an_unknown_task_says_so(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    robot(ros, launch_task_manager, topic_prefix)
    client.wait_until_available()

    with pytest.raises(TaskManagerError, match="knows no task 'nobody'"):
        client.why('nobody')


def test_an_unknown_event_kind_or_status_from_a_newer_node_stops_nothing(
    ros: RosHarness, client: TaskManagerClient
) -> None:
    """No Task Manager here: the test plays a newer one on its topics."""
    events = ros.node.create_publisher(TaskEventArray, TASK_EVENT_BATCHES_TOPIC, qos.TASK_EVENTS)
    active = ros.node.create_publisher(ActiveTaskArray, ACTIVE_TASKS_TOPIC, qos.LATEST_ACTIVE_TASKS)
    log = EventLog()
    client.on_task_event(log)
    wait_until(lambda: client.connected and client.events_connected, 'the client connected')
    # The client seeing the publishers is not enough: each publisher matches the client's
    # subscription in its own time, and a volatile message sent before is never delivered.
    wait_until(
        lambda: events.get_subscription_count() > 0 and active.get_subscription_count() > 0,
        'the publishers matched the client',
    )

    def state(task_id: str, status: str, error_code: str = '') -> TaskStateMessage:
        return TaskStateMessage(
            task_id=task_id, task_name='x', task_status=status, error_code=error_code
        )

    strange_event = TaskEventMessage(event='TELEPORTED', task=state('new', 'HOVERING'))
    ended_event = TaskEventMessage(event='ENDED', task=state('ok', 'DONE', 'out_of_ink'))
    events.publish(TaskEventArray(events=[strange_event, ended_event]))
    active.publish(ActiveTaskArray(active_tasks=[ActiveTask(task_id='a', task_status='HOVERING')]))

    strange = log.wait_for('new', TaskEventKind.DECIDED)
    assert strange.task.status is TaskStatus.RECEIVED
    ended = log.wait_for('ok', TaskEventKind.ENDED)  # the executor went on
    assert (ended.task.status, ended.task.error_code) == (TaskStatus.DONE, ErrorCode.NONE)
    assert [(t.task_id, t.status) for t in client.active_tasks()] == [('a', TaskStatus.RECEIVED)]
