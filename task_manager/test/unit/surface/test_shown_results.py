"""taskctl results --follow's account of the results it showed (ShownResults): each result
once, whatever the order, and where to read the history from when events went missing; and the
follow itself with its client's iterator of events and losses. (Through real DDS, taskctl
stopped while the node floods it: see the closing note of 2026-11-30, the client at times heard
nothing more at all.)"""

import queue
from collections.abc import Iterator
from datetime import UTC, datetime

from hypothesis import given
from hypothesis import strategies as st

from task_manager.cli.verbs.watch import ABOVE_MAX, ShownResults, _results_of_events
from task_manager.client import EventsLost, TaskEvent, TaskEventKind, TaskState
from task_manager.core.status import TaskStatus


def test_in_turn_the_floor_follows_the_newest() -> None:
    shown = ShownResults()

    assert [shown.first_time(n) for n in (7, 8, 9)] == [True, True, True]
    assert (shown.floor, shown.above) == (9, set())


def test_after_a_gap_the_floor_stays_below_it_until_the_history_fills_it() -> None:
    shown = ShownResults()
    shown.first_time(7)
    shown.first_time(12)  # 8 to 11 lost with their events

    assert (shown.floor, shown.above) == (7, {12})
    assert [shown.first_time(n) for n in (8, 9, 10, 11, 12)] == [True] * 4 + [False]
    assert (shown.floor, shown.above) == (12, set())


def test_what_the_history_no_longer_has_is_given_up_once_read() -> None:
    shown = ShownResults()
    shown.first_time(7)
    shown.first_time(12)

    shown.filled()

    assert (shown.floor, shown.above) == (12, set())
    assert not shown.first_time(9)


def test_a_result_without_a_number_is_always_shown() -> None:
    shown = ShownResults()

    assert shown.first_time(0) and shown.first_time(0)
    assert shown.floor is None


def test_numbers_never_filled_are_given_up_beyond_a_bound() -> None:
    shown = ShownResults()
    shown.first_time(1)  # 2 never comes: a number given without an event

    for number in range(3, ABOVE_MAX + 4):
        shown.first_time(number)

    assert len(shown.above) <= ABOVE_MAX
    assert shown.floor == ABOVE_MAX + 3


@given(st.lists(st.integers(min_value=1, max_value=60)))
def test_each_number_is_new_once(numbers: list[int]) -> None:
    shown = ShownResults()

    new = [n for n in numbers if shown.first_time(n)]

    assert len(new) == len(set(new))
    assert set(new) <= set(numbers)
    assert all(n > numbers[0] for n in new[1:])  # below the first: before the following began


class HistoryOnly:
    """Stands in for taskctl's client: the events and losses the test puts, as its iterator
    gives them, and a history of ended tasks numbered 1 to `newest`."""

    def __init__(self, newest: int) -> None:
        self.arrived: queue.SimpleQueue[TaskEvent | EventsLost] = queue.SimpleQueue()
        self.kept = [ended(n) for n in range(1, newest + 1)]

    def task_events(self, *, losses: bool) -> Iterator[TaskEvent | EventsLost]:
        assert losses
        return iter(self.arrived.get, None)

    def ended_after(self, after_sequence: int) -> Iterator[TaskState]:
        return (s for s in self.kept if s.sequence > after_sequence)


def ended(sequence: int) -> TaskState:
    return TaskState(f't{sequence}', 'fib', TaskStatus.DONE, 'test', sequence=sequence)


def test_follow_fills_what_lost_events_carried_from_the_history_and_shows_each_once() -> None:
    client = HistoryOnly(newest=6)
    results = _results_of_events(client)
    event = client.arrived.put

    for number in (1, 5):  # 2 to 4 went missing; 5 came in the batch that showed it
        event(TaskEvent(TaskEventKind.ENDED, datetime.now(UTC), ended(number)))
    event(EventsLost(3))
    for number in range(6, 12):  # 6 already read from the history, the others new
        event(TaskEvent(TaskEventKind.ENDED, datetime.now(UTC), ended(number)))

    shown = [next(results).task_id for _ in range(7)]

    assert shown == ['t1', 't5', 't2', 't3', 't4', 't6', 't7']
