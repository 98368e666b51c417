"""TaskState and TaskEvent, the Python client's view of the event stream, from real messages."""

from datetime import UTC, datetime, timedelta

from builtin_interfaces.msg import Time
from task_manager_msgs.msg import TaskEvent as TaskEventMessage
from task_manager_msgs.msg import TaskState as TaskStateMessage

from task_manager.client import TaskEvent, TaskEventKind, TaskResult, TaskState
from task_manager.core.status import ErrorCode, TaskStatus

RECEIVED = Time(sec=1_800_000_000, nanosec=250_000_000)
STARTED = Time(sec=1_800_000_001, nanosec=500_000)
ENDED = Time(sec=1_800_000_003, nanosec=999_999_999)


def _at(stamp: Time) -> datetime:
    return datetime.fromtimestamp(stamp.sec, UTC) + timedelta(microseconds=stamp.nanosec // 1000)


def test_stamps_become_aware_datetimes_and_zero_is_none() -> None:
    message = TaskStateMessage(
        task_id='t1',
        task_name='nav',
        source='UI',
        task_status='IN_PROGRESS',
        mission_id='m1',
        received=RECEIVED,
        started=STARTED,
        feedback='{"distance_remaining": 1.5}',
    )

    state = TaskState.from_message(message)

    assert state.received_at == datetime(2027, 1, 15, 8, 0, 0, 250_000, tzinfo=UTC)
    assert state.started_at == _at(STARTED) and state.ended_at is None
    assert (state.status, state.error_code, state.mission_id) == (
        TaskStatus.IN_PROGRESS,
        ErrorCode.NONE,
        'm1',
    )
    assert state.feedback == {'distance_remaining': 1.5} and state.result is None
    assert not state.is_final
    assert state.elapsed(_at(STARTED) + timedelta(seconds=2)) == timedelta(seconds=2)


def test_an_ended_state_is_a_result_with_its_duration() -> None:
    message = TaskStateMessage(
        task_id='t2',
        task_name='dock',
        source='CLI',
        task_status='ERROR',
        error_code='task_start_failed',
        received=RECEIVED,
        started=STARTED,
        ended=ENDED,
        task_result='{"error": "no dock"}',
    )

    result = TaskState.from_message(message).to_result()

    assert (result.status, result.error_message) == (TaskStatus.ERROR, 'no dock')
    assert result.ended_at == _at(ENDED)
    assert result.duration == _at(ENDED) - _at(STARTED)


def test_a_task_that_never_started_has_no_duration() -> None:
    message = TaskStateMessage(
        task_id='t3', task_name='x', task_status='ERROR', received=RECEIVED, ended=ENDED
    )

    state = TaskState.from_message(message)

    assert state.elapsed() is None and state.to_result().duration is None
    assert TaskResult('t4', 'x', TaskStatus.DONE, ErrorCode.NONE, {}).duration is None


def test_feedback_that_is_not_a_json_object_is_kept_raw() -> None:
    message = TaskStateMessage(task_id='t5', task_status='IN_PROGRESS', feedback='[1, 2]')

    assert TaskState.from_message(message).feedback == {'raw': '[1, 2]'}


def test_an_event_has_its_kind_stamp_and_state() -> None:
    message = TaskEventMessage(
        event=TaskEventMessage.ENDED,
        stamp=ENDED,
        task=TaskStateMessage(task_id='t6', task_status='DONE', ended=ENDED),
    )

    event = TaskEvent.from_message(message)

    assert (event.kind, event.stamp, event.task.task_id) == (
        TaskEventKind.ENDED,
        _at(ENDED),
        't6',
    )
