"""The client's records of what decides what runs (issue 29): a task state's priority, place in
the queue, attempt and decisions, an event's reason, and values of a newer Task Manager."""

import json
from datetime import UTC, datetime

from builtin_interfaces.msg import Time
from task_manager_msgs.msg import TaskDoneResult
from task_manager_msgs.msg import TaskEvent as TaskEventMessage
from task_manager_msgs.msg import TaskState as TaskStateMessage

from task_manager.client import Decision, TaskEvent, TaskEventKind, TaskResult, TaskState
from task_manager.client.records import parse_decisions
from task_manager.core.status import ErrorCode, TaskStatus

QUEUED_AT = 1_800_000_000.5


def test_a_queued_state_has_its_place_priority_attempt_and_decisions() -> None:
    decisions = [
        {'at': QUEUED_AT, 'decision': 'queued', 'reason': 'queued behind d (priority 5)'},
        {'at': QUEUED_AT + 1, 'decision': 'reprioritized', 'reason': 'priority 0 -> 3'},
    ]
    message = TaskStateMessage(
        task_id='t1',
        task_status='QUEUED',
        queue_position=2,
        priority=3,
        attempt=1,
        decisions=json.dumps(decisions),
    )

    state = TaskState.from_message(message)

    assert (state.status, state.queue_position, state.priority, state.attempt) == (
        TaskStatus.QUEUED,
        2,
        3,
        1,
    )
    assert state.decisions == [
        Decision(datetime.fromtimestamp(QUEUED_AT, UTC), 'queued', 'queued behind d (priority 5)'),
        Decision(datetime.fromtimestamp(QUEUED_AT + 1, UTC), 'reprioritized', 'priority 0 -> 3'),
    ]
    assert not state.is_final and state.elapsed() is None


def test_decisions_that_cannot_be_read_are_left_out() -> None:
    text = json.dumps(
        [
            {'at': 'yesterday', 'decision': 'queued', 'reason': 'x'},
            {'at': QUEUED_AT, 'reason': 'no decision'},
            'refused',
            {'at': QUEUED_AT, 'decision': 'teleported', 'reason': 'a newer kind'},
            {'at': QUEUED_AT, 'decision': 'started'},
        ]
    )

    assert [(d.decision, d.reason) for d in parse_decisions(text)] == [
        ('teleported', 'a newer kind'),
        ('started', ''),
    ]
    assert parse_decisions('') == parse_decisions('{"a": 1}') == parse_decisions('[') == []


def test_an_event_carries_its_reason() -> None:
    message = TaskEventMessage(
        event='QUEUED',
        stamp=Time(sec=1_800_000_000),
        task=TaskStateMessage(task_id='t1', task_status='QUEUED', queue_position=1),
        reason='queued behind drive-1 (priority 5), which holds base',
    )

    event = TaskEvent.from_message(message)

    assert (event.kind, event.task.queue_position) == (TaskEventKind.QUEUED, 1)
    assert event.reason == 'queued behind drive-1 (priority 5), which holds base'


def test_values_of_a_newer_task_manager_are_taken_as_known_ones() -> None:
    active = TaskStateMessage(task_id='a', task_status='HOVERING', error_code='out_of_ink')
    ended = TaskStateMessage(task_id='e', task_status='VANISHED', ended=Time(sec=1_800_000_000))
    event = TaskEventMessage(event='TELEPORTED', task=active)
    result = TaskDoneResult(task_id='r', task_status='VANISHED', error_code='out_of_ink')

    assert TaskState.from_message(active).status is TaskStatus.RECEIVED
    assert TaskState.from_message(active).error_code is ErrorCode.NONE
    assert TaskState.from_message(ended).status is TaskStatus.ERROR
    assert TaskEvent.from_message(event).kind is TaskEventKind.DECIDED
    assert TaskResult.from_message(result).status is TaskStatus.ERROR
