"""What a task keeps of the decisions taken about it: at most DECISIONS_PER_TASK_MAX, its first
and its newest with a count of those left out, each reason cut to REASON_MAX_CHARACTERS."""

from task_manager.client.records import parse_decisions
from task_manager.core.admission.decisions import (
    KEPT_FIRST,
    DecisionKind,
    decisions_from_json,
    decisions_to_json,
)
from task_manager.core.bounds import DECISIONS_PER_TASK_MAX, REASON_MAX_CHARACTERS
from task_manager.core.task import TaskRecord
from task_manager.core.task_spec import InterfaceName, TaskKind, TaskSpec
from task_manager.gateway.documents import decisions_json
from task_manager.testing.gateway import check

REPRIORITIZED = DecisionKind.REPRIORITIZED
KEPT_NEWEST = DECISIONS_PER_TASK_MAX - KEPT_FIRST - 1


def make_record() -> TaskRecord:
    interface = InterfaceName('test_msgs', TaskKind.ACTION, 'Fibonacci')
    spec = TaskSpec(task_name='fib', topic='/fib', interface=interface)
    return TaskRecord(task_id='t1', spec=spec, source='test', received_at=1.0)


def reprioritized(times: int) -> TaskRecord:
    """A record queued at 0, then reprioritized `times` times (the n-th at n, reason 'n')."""
    record = make_record()
    record.note(DecisionKind.QUEUED, 'queued behind d1', now=0.0)
    for n in range(1, times + 1):
        record.note(REPRIORITIZED, str(n), now=float(n))
    return record


def test_up_to_the_bound_every_decision_is_kept() -> None:
    record = reprioritized(DECISIONS_PER_TASK_MAX - 1)

    assert len(record.decisions) == DECISIONS_PER_TASK_MAX
    assert [note.reason for note in record.decisions[1:]] == [
        str(n) for n in range(1, DECISIONS_PER_TASK_MAX)
    ]
    assert all(note.decision is not DecisionKind.OMITTED for note in record.decisions)


def test_a_task_reprioritized_1000_times_keeps_its_first_and_newest_and_counts_the_rest() -> None:
    record = reprioritized(1000)

    notes = record.decisions
    assert len(notes) == DECISIONS_PER_TASK_MAX
    assert notes[0].reason == 'queued behind d1'
    assert [n.reason for n in notes[1:KEPT_FIRST]] == [str(n) for n in range(1, KEPT_FIRST)]
    marker = notes[KEPT_FIRST]
    assert marker.decision is DecisionKind.OMITTED
    assert marker.omitted == 1001 - DECISIONS_PER_TASK_MAX + 1  # 1,001 decisions, 99 kept
    assert marker.at == 1000.0 - KEPT_NEWEST  # the newest of those left out
    assert f'{marker.omitted} decisions left out' in marker.reason
    assert [n.reason for n in notes[KEPT_FIRST + 1 :]] == [
        str(n) for n in range(1001 - KEPT_NEWEST, 1001)
    ]


def test_the_first_decision_left_out_makes_room_for_the_count() -> None:
    record = reprioritized(DECISIONS_PER_TASK_MAX)

    assert len(record.decisions) == DECISIONS_PER_TASK_MAX
    assert record.decisions[KEPT_FIRST].omitted == 2
    assert record.decisions[-1].reason == str(DECISIONS_PER_TASK_MAX)


def test_a_long_reason_is_cut_with_a_note() -> None:
    record = make_record()

    note = record.note(REPRIORITIZED, 'x' * (REASON_MAX_CHARACTERS + 500), now=1.0)

    assert note.reason.startswith('x' * REASON_MAX_CHARACTERS)
    assert note.reason.endswith('(500 more characters)')
    assert len(note.reason) < REASON_MAX_CHARACTERS + 50


def test_the_count_left_out_reaches_the_client_and_the_gateways_documents() -> None:
    record = reprioritized(1000)
    text = decisions_to_json(record.decisions)

    assert decisions_from_json(text) == record.decisions
    decisions = parse_decisions(text)
    assert [d.omitted for d in decisions if d.omitted] == [record.decisions[KEPT_FIRST].omitted]
    documents = [check(document, 'decision') for document in decisions_json(decisions)]
    assert documents[KEPT_FIRST]['decision'] == 'omitted'
    assert documents[KEPT_FIRST]['omitted'] == record.decisions[KEPT_FIRST].omitted
    assert documents[0]['omitted'] == 0
    assert len(text) < 10_000  # 1,001 decisions: 66 kB before
