"""The Task Manager's own messages built from its records (messages/task_messages.py): a task
reads the same whether it is active or stored, and what a request carries reads back as sent."""

from pathlib import Path

from builtin_interfaces.msg import Time
from task_manager_msgs.msg import TaskOptions
from task_manager_msgs.srv import QueryTaskHistory

from task_manager.core.admission.decisions import DecisionKind
from task_manager.core.admission.options import OnConflict, RequestOptions
from task_manager.core.history.store import HistoryQuery, TaskHistory
from task_manager.core.names import HISTORY_QUERY_LIMIT_DEFAULT, HISTORY_QUERY_LIMIT_MAX
from task_manager.core.schedules.book import ScheduleState
from task_manager.core.schedules.schedule import OverlapPolicy, ScheduleSpec
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.core.task import TaskRecord
from task_manager.core.task_spec import InterfaceName, TaskKind, TaskSpec
from task_manager.messages import task_messages as messages
from task_manager.messages.json_codec import message_to_dict

FIB = TaskSpec('fib', '/fib', InterfaceName('test_msgs', TaskKind.ACTION, 'Fibonacci'))


def ended_record() -> TaskRecord:
    record = TaskRecord('t1', FIB, 'CLOUD:alice', task_data='{"order": 3}', received_at=10.25)
    record.priority, record.attempt, record.parent_id = 7, 2, 'mission-1'
    record.note(DecisionKind.QUEUED, 'fib is busy', now=10.5)
    record.mark_started(now=11.0)
    record.mark_ended(TaskStatus.ERROR, {'error': 'aborted'}, ErrorCode.TIMEOUT, now=12.75)
    return record


def test_a_stored_task_reads_back_as_the_state_and_result_it_ended_with(tmp_path: Path) -> None:
    record = ended_record()
    history = TaskHistory(str(tmp_path / 'history.sqlite'))
    record.sequence = history.write(record)
    history.flush()
    (row,) = history.query(HistoryQuery(task_id='t1'))
    history.close()

    live, stored = (
        message_to_dict(messages.task_state_msg(record)),
        message_to_dict(messages.task_state_of_row(row)),
    )

    assert stored == {**live, 'feedback': '', 'queue_position': 0}  # what a row does not keep
    assert live['received'] == {'sec': 10, 'nanosec': 250_000_000}
    assert live['mission_id'] == 'mission-1' and live['priority'] == 7 and live['attempt'] == 2
    assert message_to_dict(messages.result_msg_of_row(row)) == message_to_dict(
        messages.result_msg(record)
    )
    assert messages.result_fields(record) == {
        'task_id': 't1',
        'task_result': '{"error":"aborted"}',
        'task_status': 'ERROR',
        'error_code': 'timeout',
    }


def test_a_stamp_is_zero_for_not_yet_and_reads_back_in_seconds() -> None:
    assert messages.stamp(None) == Time()
    assert messages.seconds_of(Time()) is None
    assert messages.stamp(1.5) == Time(sec=1, nanosec=500_000_000)
    assert messages.seconds_of(messages.stamp(1_700_000_000.125)) == 1_700_000_000.125


def test_options_read_back_as_sent_and_an_unknown_on_conflict_is_the_error() -> None:
    options = RequestOptions(priority=-3, on_conflict=OnConflict.QUEUE, queue_timeout_sec=2.5)

    for sent in (options, RequestOptions()):
        assert messages.options_of_message(messages.task_options_msg(sent)) == sent
    unknown = messages.options_of_message(TaskOptions(on_conflict='later'))
    assert unknown.on_conflict is None and 'later' in unknown.error


def test_a_history_query_takes_the_default_limit_and_at_most_the_largest() -> None:
    asked = QueryTaskHistory.Request(task_name='fib', ended_after=messages.stamp(5.0), limit=0)
    too_many = QueryTaskHistory.Request(limit=HISTORY_QUERY_LIMIT_MAX + 1)

    assert messages.history_query(asked) == HistoryQuery(
        task_name='fib', ended_after=5.0, limit=HISTORY_QUERY_LIMIT_DEFAULT
    )
    assert messages.history_query(too_many).limit == HISTORY_QUERY_LIMIT_MAX


def test_a_schedule_message_has_its_spec_and_state_and_no_next_run_while_disabled() -> None:
    spec = ScheduleSpec(
        's1', 'patrol', '{"zone": 1}', 'WEB:alice', 100.0, period_sec=60.0,
        overlap=OverlapPolicy.SKIP, options={'priority': 4},
    )  # fmt: skip
    state = ScheduleState(
        enabled=False, next_run=160.0, last_run=100.0, last_task_id='run-1', last_status='DONE',
        run_count=1, missed_count=2, skipped_count=3,
    )  # fmt: skip

    sent = message_to_dict(messages.schedule_msg(spec, state))

    assert (sent['schedule_id'], sent['task_name'], sent['task_data'], sent['created_by']) == (
        's1', 'patrol', '{"zone": 1}', 'WEB:alice'
    )  # fmt: skip
    assert (sent['period_sec'], sent['overlap'], sent['enabled']) == (
        60.0,
        str(OverlapPolicy.SKIP),
        False,
    )
    assert (sent['run_count'], sent['missed_count'], sent['skipped_count']) == (1, 2, 3)
    assert (sent['last_task_id'], sent['last_status']) == ('run-1', 'DONE')
    assert sent['next_run'] == {'sec': 0, 'nanosec': 0}  # disabled: no run to come
    assert sent['last_run'] == {'sec': 100, 'nanosec': 0}
    assert sent['options']['has_priority'] and sent['options']['priority'] == 4
