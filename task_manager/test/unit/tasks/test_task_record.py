"""Tests of a task's lifecycle record and of how server outcomes map to end statuses."""

import itertools
import time
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from task_manager.core.errors import InvalidTransition
from task_manager.core.status import CancelReason, ErrorCode, ServerOutcome, TaskStatus
from task_manager.core.task import (
    TaskEnd,
    TaskRecord,
    TaskRequest,
    status_for_action_outcome,
    status_for_service_response,
)
from task_manager.core.task_spec import InterfaceName, TaskKind, TaskSpec

RECEIVED, IN_PROGRESS, PAUSED = TaskStatus.RECEIVED, TaskStatus.IN_PROGRESS, TaskStatus.PAUSED
DONE, ERROR, CANCELED = TaskStatus.DONE, TaskStatus.ERROR, TaskStatus.CANCELED
QUEUED = TaskStatus.QUEUED
FINAL = (DONE, ERROR, CANCELED)
ALLOWED = {
    (RECEIVED, QUEUED),
    (QUEUED, IN_PROGRESS),
    (QUEUED, ERROR),
    (QUEUED, CANCELED),
    (RECEIVED, IN_PROGRESS),
    (RECEIVED, ERROR),
    (RECEIVED, CANCELED),
    (IN_PROGRESS, DONE),
    (IN_PROGRESS, ERROR),
    (IN_PROGRESS, CANCELED),
    (IN_PROGRESS, PAUSED),
    (PAUSED, IN_PROGRESS),
    (PAUSED, DONE),
    (PAUSED, ERROR),
    (PAUSED, CANCELED),
}
ALL_PAIRS = list(itertools.product(TaskStatus, TaskStatus))
FORBIDDEN = [pair for pair in ALL_PAIRS if pair not in ALLOWED]


def make_spec(name: str = 'fib', kind: TaskKind = TaskKind.ACTION, **options: Any) -> TaskSpec:
    interface = InterfaceName('test_msgs', kind, 'Fibonacci' if kind is TaskKind.ACTION else 'X')
    return TaskSpec(task_name=name, topic=f'/{name}', interface=interface, **options)


def make_record(task_id: str = 't1', **spec_options: Any) -> TaskRecord:
    return TaskRecord(
        task_id=task_id, spec=make_spec(**spec_options), source='test', received_at=1.0
    )


def record_in(status: TaskStatus) -> TaskRecord:
    """A record brought to `status` through allowed steps (started at 2.0, ended at 3.0)."""
    record = make_record()
    if status is QUEUED:
        record.mark_queued(1)
    elif status is not RECEIVED:
        record.mark_started(now=2.0)
    if status is PAUSED:
        record.mark_paused('operator', now=2.5)
    if status.is_final:
        record.mark_ended(status, {'sequence': [0, 1]}, ErrorCode.NONE, now=3.0)
    assert record.status is status
    return record


def move(record: TaskRecord, status: TaskStatus, now: float) -> None:
    """Ask the record to go to `status` through its public API."""
    if status is IN_PROGRESS and record.status is PAUSED:
        record.mark_resumed('operator', now=now)
    elif status is IN_PROGRESS:
        record.mark_started(now=now)
    elif status is PAUSED:
        record.mark_paused('operator', now=now)
    elif status is QUEUED:
        record.mark_queued(1)
    else:  # RECEIVED has no method of its own; mark_ended must refuse it like any other step
        record.mark_ended(status, {'n': 1}, ErrorCode.TASK_START_FAILED, now=now)


def snapshot(record: TaskRecord) -> tuple[Any, ...]:
    return (
        record.status,
        record.started_at,
        record.ended_at,
        dict(record.result),
        record.error_code,
        len(record.pauses),
    )


# ---- transitions -----------------------------------------------------------------------------


def test_a_new_record_is_received() -> None:
    record = make_record()
    assert record.status is RECEIVED
    assert record.error_code is ErrorCode.NONE
    assert record.result == {}
    assert record.started_at is None
    assert record.ended_at is None
    assert record.latest_feedback is None
    assert record.feedback_at is None
    assert record.cancel_reason is None
    assert record.parent_id == ''
    assert not record.is_final
    assert record.task_name == 'fib'


def test_status_is_final_only_for_end_statuses() -> None:
    assert [status for status in TaskStatus if status.is_final] == list(FINAL)


@pytest.mark.parametrize(('before', 'after'), sorted(ALLOWED))
def test_allowed_transitions(before: TaskStatus, after: TaskStatus) -> None:
    record = record_in(before)
    move(record, after, now=9.0)
    assert record.status is after
    assert record.is_final is after.is_final


@pytest.mark.parametrize(('before', 'after'), FORBIDDEN)
def test_every_other_transition_is_invalid_and_changes_nothing(
    before: TaskStatus, after: TaskStatus
) -> None:
    record = record_in(before)
    unchanged = snapshot(record)
    with pytest.raises(InvalidTransition):
        move(record, after, now=9.0)
    assert snapshot(record) == unchanged


def test_forbidden_list_covers_every_other_pair() -> None:
    assert len(ALL_PAIRS) == 49
    assert len(FORBIDDEN) == 34


@pytest.mark.parametrize('before', [RECEIVED, IN_PROGRESS, PAUSED])
@pytest.mark.parametrize('status', [RECEIVED, IN_PROGRESS, PAUSED])
def test_mark_ended_refuses_a_status_that_is_not_an_end(
    before: TaskStatus, status: TaskStatus
) -> None:
    record = record_in(before)
    with pytest.raises(InvalidTransition, match='is not an end status'):
        record.mark_ended(status, now=9.0)
    assert record.status is before
    assert record.ended_at is None


# ---- timestamps, result, feedback, cancel ----------------------------------------------------


def test_received_at_is_set_on_creation() -> None:
    before = time.time()
    record = TaskRecord(task_id='t1', spec=make_spec(), source='test')
    assert before <= record.received_at <= time.time()


def test_started_at_and_ended_at_are_set_by_their_steps() -> None:
    record = make_record()
    record.mark_started(now=10.0)
    assert (record.received_at, record.started_at, record.ended_at) == (1.0, 10.0, None)
    record.mark_ended(DONE, {'sequence': [0, 1, 1]}, now=12.5)
    assert (record.received_at, record.started_at, record.ended_at) == (1.0, 10.0, 12.5)
    assert record.result == {'sequence': [0, 1, 1]}
    assert record.error_code is ErrorCode.NONE


def test_steps_without_now_use_the_clock() -> None:
    record = make_record()
    before = time.time()
    record.mark_started()
    record.mark_ended(CANCELED)
    after = time.time()
    assert record.started_at is not None and record.ended_at is not None
    assert before <= record.started_at <= record.ended_at <= after


def test_a_task_that_never_started_ends_with_its_error_code() -> None:
    record = make_record()
    record.mark_ended(ERROR, error_code=ErrorCode.TASK_START_FAILED, now=4.0)
    assert record.status is ERROR
    assert record.error_code is ErrorCode.TASK_START_FAILED
    assert record.result == {}
    assert record.started_at is None
    assert record.ended_at == 4.0


def test_record_feedback_keeps_the_latest_feedback_and_its_time() -> None:
    record = record_in(IN_PROGRESS)
    record.record_feedback({'sequence': [0]}, now=5.0)
    assert (record.latest_feedback, record.feedback_at) == ({'sequence': [0]}, 5.0)
    record.record_feedback({'sequence': [0, 1]}, now=6.0)
    assert (record.latest_feedback, record.feedback_at) == ({'sequence': [0, 1]}, 6.0)


def test_record_feedback_without_now_uses_the_clock() -> None:
    record = record_in(IN_PROGRESS)
    before = time.time()
    record.record_feedback({'remaining_time': 1})
    assert record.feedback_at is not None
    assert before <= record.feedback_at <= time.time()


def test_request_cancel_keeps_the_first_reason() -> None:
    record = record_in(IN_PROGRESS)
    record.request_cancel(CancelReason.CONFLICT)
    record.request_cancel(CancelReason.STOP)
    record.request_cancel(CancelReason.CLIENT)
    assert record.cancel_reason is CancelReason.CONFLICT
    assert record.status is IN_PROGRESS  # asking for a cancel is not ending


def test_task_request_and_task_end_defaults() -> None:
    request = TaskRequest(task_id='t1', task_name='fib', source='cloud', task_data='{}')
    assert request.parent_id == ''
    end = TaskEnd(DONE)
    assert end.result == {}
    assert end.error_code is ErrorCode.NONE
    assert TaskEnd(ERROR).result is not end.result  # no shared mutable default


# ---- end statuses ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ('outcome', 'cancel_reported_as_success', 'expected'),
    [
        (ServerOutcome.SUCCEEDED, False, DONE),
        (ServerOutcome.SUCCEEDED, True, DONE),
        (ServerOutcome.ABORTED, False, ERROR),
        (ServerOutcome.ABORTED, True, ERROR),
        (ServerOutcome.CANCELED, False, CANCELED),
        (ServerOutcome.CANCELED, True, DONE),
    ],
)
def test_status_for_action_outcome(
    outcome: ServerOutcome, cancel_reported_as_success: bool, expected: TaskStatus
) -> None:
    spec = make_spec(cancel_reported_as_success=cancel_reported_as_success)
    assert status_for_action_outcome(outcome, spec) is expected


@pytest.mark.parametrize(
    ('success_field', 'response', 'expected'),
    [
        ('', {}, DONE),
        ('', {'success': False}, DONE),
        ('success', {'success': True, 'message': ''}, DONE),
        ('success', {'success': False, 'message': 'nope'}, ERROR),
        ('success', {'message': 'no such field'}, DONE),
        ('ok', {'success': False, 'ok': True}, DONE),
        ('ok', {'success': True, 'ok': False}, ERROR),
    ],
)
def test_status_for_service_response(
    success_field: str, response: dict[str, Any], expected: TaskStatus
) -> None:
    spec = make_spec(kind=TaskKind.SERVICE, service_success_field=success_field)
    assert status_for_service_response(response, spec) is expected


# ---- property --------------------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(steps=st.lists(st.sampled_from(list(TaskStatus)), max_size=6))
def test_any_sequence_of_steps_follows_the_lifecycle(steps: list[TaskStatus]) -> None:
    record = make_record()
    expected = RECEIVED
    started_at: float | None = None
    ended_at: float | None = None
    for now, target in enumerate(steps, start=10):
        if (expected, target) in ALLOWED:
            move(record, target, now=float(now))
            if target is IN_PROGRESS and expected in (RECEIVED, QUEUED):
                started_at = float(now)
            elif target.is_final:
                ended_at = float(now)
            expected = target
        else:
            with pytest.raises(InvalidTransition):
                move(record, target, now=float(now))
        assert record.status is expected
        assert (record.started_at, record.ended_at) == (started_at, ended_at)


def test_pauses_record_who_and_when_and_paused_time_is_not_running_time() -> None:
    record = record_in(IN_PROGRESS)
    record.mark_paused('operator', now=4.0)
    record.mark_resumed('CLOUD', now=6.5)
    record.mark_paused('CLI', now=8.0)
    assert record.paused_sec(now=9.0) == 3.5  # 2.5 s closed, 1 s open until now
    record.mark_ended(CANCELED, now=10.0)
    assert [(p.paused_at, p.paused_by, p.resumed_at, p.resumed_by) for p in record.pauses] == [
        (4.0, 'operator', 6.5, 'CLOUD'),
        (8.0, 'CLI', None, ''),
    ]
    assert record.paused_sec() == 4.5  # the open pause counts until the end


def test_started_only_once_and_resumed_only_when_paused() -> None:
    record = record_in(PAUSED)
    with pytest.raises(InvalidTransition):
        record.mark_started(now=5.0)
    running = record_in(IN_PROGRESS)
    with pytest.raises(InvalidTransition):
        running.mark_resumed('operator', now=5.0)
    assert (record.status, record.started_at, running.status) == (PAUSED, 2.0, IN_PROGRESS)
