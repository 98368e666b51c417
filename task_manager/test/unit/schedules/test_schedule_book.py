"""The schedule book: what is due and when, catch-up, max_runs, enabling, overlap decisions."""

import math
import random
import time
from datetime import UTC, datetime
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from task_manager.core.schedules.book import (
    Firing,
    RunAction,
    ScheduleBook,
    ScheduleState,
    overlap_action,
    run_source,
    run_task_id,
)
from task_manager.core.schedules.schedule import OverlapPolicy, ScheduleSpec

T0 = datetime(2026, 1, 1, tzinfo=UTC).timestamp()
DAY, WEEK = 86400, 7 * 86400


def spec(schedule_id: str = 's', **when: Any) -> ScheduleSpec:
    return ScheduleSpec(schedule_id, 'patrol', '{}', 'test', T0, **when)


def book_of(*specs: ScheduleSpec) -> ScheduleBook:
    book = ScheduleBook()
    for s in specs:
        book.add(s)
    return book


def state(book: ScheduleBook, schedule_id: str = 's') -> ScheduleState:
    found = book.get(schedule_id)
    assert found is not None
    return found[1]


def start_all(book: ScheduleBook, firings: list[Firing], now: float) -> None:
    for firing in firings:
        run_number = state(book, firing.schedule_id).run_count + 1
        book.run_started(firing.schedule_id, run_task_id(firing.schedule_id, run_number), now)


def test_run_ids_and_sources_name_the_schedule() -> None:
    assert run_task_id('nightly', 3) == 'nightly-run-3'
    assert run_source('nightly') == 'schedule:nightly'


# ---- firing on time and late -------------------------------------------------------------


def test_a_new_schedule_waits_for_its_first_fire_time_then_fires_on_time() -> None:
    book = book_of(spec(period_sec=60))
    assert book.next_due() == T0 + 60
    assert book.take_due(T0 + 59.9) == ([], [])

    assert book.take_due(T0 + 60) == ([Firing('s', T0 + 60, 0)], ['s'])

    assert (state(book).next_run, state(book).missed_count) == (T0 + 120, 0)
    assert book.next_due() == T0 + 120


def test_a_run_late_within_the_grace_runs_once_for_its_due_time() -> None:
    book = book_of(spec(period_sec=3600, misfire_grace_sec=900))
    firings, _ = book.take_due(T0 + 3600 + 899)
    assert firings == [Firing('s', T0 + 3600, 0)]
    assert (state(book).next_run, state(book).missed_count) == (T0 + 7200, 0)


def test_a_run_later_than_the_grace_is_missed_and_counted() -> None:
    book = book_of(spec(period_sec=3600, misfire_grace_sec=900))
    assert book.take_due(T0 + 3600 + 901) == ([], ['s'])
    assert (state(book).next_run, state(book).missed_count) == (T0 + 7200, 1)


def test_a_one_shot_fires_once_then_is_finished() -> None:
    book = book_of(spec(at=T0 + 10))
    assert book.take_due(T0 + 10)[0] == [Firing('s', T0 + 10, 0)]
    assert state(book).next_run is None
    assert book.next_due() is None
    assert book.take_due(T0 + 1e6) == ([], [])


def test_a_one_shot_missed_beyond_the_grace_is_finished_and_counted() -> None:
    book = book_of(spec(at=T0 + 10, misfire_grace_sec=60))
    assert book.take_due(T0 + 100) == ([], ['s'])
    assert (state(book).next_run, state(book).missed_count) == (None, 1)


def test_a_day_of_missed_one_second_periods_coalesces_into_one_firing() -> None:
    book = book_of(spec(period_sec=1, misfire_grace_sec=900))
    now = T0 + 1 + DAY + 0.5  # down from the first due time for a day

    firings, changed = book.take_due(now)

    assert firings == [Firing('s', T0 + 1 + DAY, DAY)]  # 86,401 due times, the latest runs
    assert changed == ['s']
    assert (state(book).missed_count, state(book).next_run) == (DAY, T0 + 2 + DAY)


def test_coalescing_millisecond_periods_does_not_walk_them() -> None:
    book = book_of(spec(period_sec=0.001))
    began = time.perf_counter()
    (firing,), _ = book.take_due(T0 + DAY)
    assert time.perf_counter() - began < 0.1  # 86.4 million due times
    assert firing.coalesced == 86_399_999
    assert firing.due_at == pytest.approx(T0 + DAY)


def test_a_cron_burst_after_a_week_of_downtime_coalesces_into_one_firing() -> None:
    book = book_of(spec(cron='*/15 * * * *'))
    firings, _ = book.take_due(T0 + WEEK + 5 * 60)
    assert firings == [Firing('s', T0 + WEEK, 7 * 96 - 1)]
    assert (state(book).missed_count, state(book).next_run) == (7 * 96 - 1, T0 + WEEK + 900)


def test_a_nightly_cron_missed_for_a_week_runs_no_stale_night() -> None:
    book = book_of(spec(cron='0 2 * * *', time_zone='Europe/Paris'))
    assert book.take_due(T0 + WEEK + 12 * 3600) == ([], ['s'])  # noon: every night too late
    assert state(book).missed_count == 8  # 1 to 8 January, 02:00 in Paris


def test_due_schedules_fire_in_due_order_and_the_rest_wait() -> None:
    book = book_of(spec('b', period_sec=20), spec('a', period_sec=10), spec('c', period_sec=99))
    firings, changed = book.take_due(T0 + 25)
    assert [(f.schedule_id, f.due_at) for f in firings] == [('a', T0 + 20), ('b', T0 + 20)]
    assert firings[0].coalesced == 1  # a was due at 10 and 20
    assert changed == ['a', 'b']
    assert book.next_due() == T0 + 30


def test_ten_thousand_schedules_fire_in_the_order_a_brute_force_minimum_gives() -> None:
    rng = random.Random(7)
    periods = {f's{n}': rng.uniform(1, 1000) for n in range(10_000)}
    book = ScheduleBook()
    for key, period in periods.items():
        book.add(spec(key, period_sec=period))
    # the brute force: schedule key's next due time is (T0 + period) + index[key] * period
    index = dict.fromkeys(periods, 0)

    def expected(key: str) -> float:
        return T0 + periods[key] + index[key] * periods[key]

    in_book, now, fired = 0.0, T0, 0
    while now < T0 + 300:
        earliest = min(expected(key) for key in periods)
        began = time.perf_counter()
        assert book.next_due() == earliest
        now = earliest + rng.uniform(0, 3)
        firings, changed = book.take_due(now)
        in_book += time.perf_counter() - began
        due = sorted((expected(key), key) for key in periods if expected(key) <= now)
        assert [f.schedule_id for f in firings] == [key for _, key in due] == changed
        for firing, (_, key) in zip(firings, due, strict=True):
            late = math.floor((now - expected(key)) / periods[key])  # due times coalesced
            index[key] += late
            assert (firing.due_at, firing.coalesced) == (expected(key), late)
            index[key] += 1
        fired += len(firings)
    assert fired > 5000
    assert in_book < 1.0  # about 0.05 s: the time goes to the brute force


def test_taking_due_schedules_costs_the_due_ones_not_all() -> None:
    book = ScheduleBook()
    for n in range(10_000):
        book.add(spec(f's{n}', period_sec=1000 + n))
    began = time.perf_counter()
    for step in range(1000):
        book.take_due(T0 + 1000 + step * 0.01)
        book.next_due()
    # about 1 ms; a scan of all 10,000 at each call would take over half a second
    assert time.perf_counter() - began < 0.25


# ---- window and max_runs -----------------------------------------------------------------


def test_a_schedule_reaching_its_end_is_finished() -> None:
    book = book_of(spec(period_sec=10, end=T0 + 25))
    assert book.take_due(T0 + 20)[0] == [Firing('s', T0 + 20, 1)]
    assert state(book).next_run is None
    assert book.next_due() is None


def test_a_schedule_stops_after_max_runs_started() -> None:
    book = book_of(spec(period_sec=10, max_runs=2))
    for now in (T0 + 10, T0 + 20):
        firings, _ = book.take_due(now)
        start_all(book, firings, now)
    assert (state(book).run_count, state(book).next_run) == (2, None)
    assert book.take_due(T0 + 1000) == ([], [])


def test_max_runs_counts_firings_not_yet_started() -> None:
    book = book_of(spec(period_sec=10, max_runs=2))
    book.take_due(T0 + 10)
    book.take_due(T0 + 20)
    assert (state(book).run_count, state(book).next_run) == (0, None)


def test_a_firing_skipped_by_the_overlap_policy_gives_its_max_runs_slot_back() -> None:
    book = book_of(spec(period_sec=10, max_runs=2))
    start_all(book, book.take_due(T0 + 10)[0], T0 + 10)
    assert book.take_due(T0 + 20)[0] == [Firing('s', T0 + 20, 0)]
    assert state(book).next_run is None

    assert book.run_skipped('s')

    assert (state(book).skipped_count, state(book).next_run) == (1, T0 + 30)
    firings, _ = book.take_due(T0 + 30)
    start_all(book, firings, T0 + 30)
    assert (state(book).run_count, state(book).next_run) == (2, None)


def test_a_skipped_firing_of_an_unlimited_schedule_only_counts() -> None:
    book = book_of(spec(period_sec=10))
    book.take_due(T0 + 10)
    book.run_skipped('s')
    assert (state(book).skipped_count, state(book).next_run) == (1, T0 + 20)


# ---- runs --------------------------------------------------------------------------------


def test_a_run_records_its_start_task_and_end_status() -> None:
    book = book_of(spec(period_sec=10))
    book.take_due(T0 + 10)
    assert book.run_started('s', 's-run-1', T0 + 10.5)
    assert (state(book).run_count, state(book).last_run) == (1, T0 + 10.5)
    assert (state(book).last_task_id, state(book).last_status) == ('s-run-1', 'IN_PROGRESS')

    assert not book.run_ended('s', 'some-other-task', 'ERROR')
    assert book.run_ended('s', 's-run-1', 'DONE')
    assert state(book).last_status == 'DONE'


def test_runs_of_a_removed_schedule_are_ignored() -> None:
    book = ScheduleBook()
    assert not book.run_started('gone', 'gone-run-1', T0)
    assert not book.run_skipped('gone')
    assert not book.run_ended('gone', 'gone-run-1', 'DONE')


# ---- enabling, removing ------------------------------------------------------------------


def test_a_disabled_schedule_does_not_fire_and_keeps_its_counts() -> None:
    book = book_of(spec(period_sec=10))
    start_all(book, book.take_due(T0 + 10)[0], T0 + 10)

    assert book.set_enabled('s', False, T0 + 12)
    assert not book.set_enabled('s', False, T0 + 13)

    assert book.next_due() is None
    assert book.take_due(T0 + 100) == ([], [])
    assert (state(book).enabled, state(book).run_count, state(book).last_task_id) == (
        False, 1, 's-run-1',
    )  # fmt: skip


def test_enabling_again_resumes_after_now_without_counting_the_times_in_between() -> None:
    book = book_of(spec(period_sec=10))
    book.set_enabled('s', False, T0)

    assert book.set_enabled('s', True, T0 + 1005)

    assert (state(book).next_run, state(book).missed_count) == (T0 + 1010, 0)
    assert book.next_due() == T0 + 1010
    assert book.take_due(T0 + 1010)[0] == [Firing('s', T0 + 1010, 0)]


def test_a_one_shot_whose_time_passed_while_disabled_is_finished_when_enabled() -> None:
    book = book_of(spec(at=T0 + 10), spec('later', at=T0 + 100))
    book.set_enabled('s', False, T0)
    book.set_enabled('later', False, T0)

    book.set_enabled('s', True, T0 + 50)
    book.set_enabled('later', True, T0 + 50)

    assert (state(book, 's').next_run, state(book, 'later').next_run) == (None, T0 + 100)
    assert book.next_due() == T0 + 100


def test_a_removed_schedule_never_fires_and_its_id_can_be_used_again() -> None:
    book = book_of(spec('a', period_sec=10), spec('b', period_sec=20))
    assert book.remove('a')
    assert not book.remove('a')
    assert 'a' not in book and len(book) == 1
    assert book.next_due() == T0 + 20
    assert book.take_due(T0 + 20)[0] == [Firing('b', T0 + 20, 0)]
    book.add(spec('a', period_sec=5))
    assert book.next_due() == T0 + 5


def test_an_id_cannot_be_added_twice() -> None:
    book = book_of(spec(period_sec=10))
    with pytest.raises(ValueError, match="schedule 's' exists"):
        book.add(spec(cron='0 2 * * *'))


def test_schedules_are_listed_in_creation_order_with_copies_of_their_states() -> None:
    book = book_of(spec('z', period_sec=1), spec('a', period_sec=2), spec('m', period_sec=3))
    assert book.ids() == ['z', 'a', 'm']
    assert [s.schedule_id for s, _ in book.items()] == ['z', 'a', 'm']
    copy = state(book, 'z')
    copy.next_run = None
    assert book.next_due() == T0 + 1 == state(book, 'z').next_run
    assert book.get('nope') is None


def test_a_stored_state_is_used_as_it_is() -> None:
    book = ScheduleBook()
    stored = ScheduleState(next_run=T0 + 5, run_count=4, missed_count=1)
    assert book.add(spec(period_sec=10), stored) == stored
    assert book.next_due() == T0 + 5
    stopped = ScheduleState(enabled=False, next_run=T0 + 1)
    book.add(spec('off', period_sec=10), stopped)
    assert book.next_due() == T0 + 5


def test_many_enable_disable_changes_keep_the_heap_right() -> None:
    book = book_of(*(spec(f's{n}', period_sec=10 + n) for n in range(50)))
    for round_ in range(100):
        for n in range(50):
            book.set_enabled(f's{n}', (n + round_) % 3 != 0, T0)
    enabled = [state(book, f's{n}') for n in range(50) if state(book, f's{n}').enabled]
    assert book.next_due() == min(s.next_run for s in enabled if s.next_run is not None)
    assert len(book._heap) <= 2 * len(book._queued) + 65


# ---- overlap -----------------------------------------------------------------------------

SKIP, BUFFER_ONE = OverlapPolicy.SKIP, OverlapPolicy.BUFFER_ONE
CANCEL_OTHER, ALLOW_ALL = OverlapPolicy.CANCEL_OTHER, OverlapPolicy.ALLOW_ALL


@pytest.mark.parametrize(
    ('policy', 'previous_active', 'one_buffered', 'action'),
    [
        (SKIP, False, False, RunAction.START),
        (SKIP, True, False, RunAction.SKIP),
        (BUFFER_ONE, False, False, RunAction.START),
        (BUFFER_ONE, True, False, RunAction.BUFFER),
        (BUFFER_ONE, True, True, RunAction.SKIP),
        (CANCEL_OTHER, False, False, RunAction.START),
        (CANCEL_OTHER, True, False, RunAction.CANCEL_AND_START),
        (ALLOW_ALL, False, False, RunAction.START),
        (ALLOW_ALL, True, True, RunAction.START),
    ],
)
def test_what_a_firing_does_by_overlap_policy(
    policy: OverlapPolicy, previous_active: bool, one_buffered: bool, action: RunAction
) -> None:
    assert overlap_action(policy, previous_active, one_buffered) is action


# ---- storage -----------------------------------------------------------------------------

OPTIONAL_TIMES = st.none() | st.floats(0, 4e9)
COUNTS = st.integers(0, 2**40)


STATES = st.builds(
    ScheduleState, st.booleans(), OPTIONAL_TIMES, OPTIONAL_TIMES, st.text(), st.text(),
    COUNTS, COUNTS, COUNTS,
)  # fmt: skip


@given(STATES)
def test_a_state_round_trips_through_json_exactly(s: ScheduleState) -> None:
    assert ScheduleState.from_json(s.to_json()) == s


@pytest.mark.parametrize(
    'text',
    ['{"enabled": true}', '{}', 'null', 'nope', ScheduleState().to_json()[:-1] + ',"new":1}',
     ScheduleState().to_json().replace('"enabled":true', '"enabled":1')],
)  # fmt: skip
def test_a_stored_state_this_version_cannot_read_is_refused(text: str) -> None:
    with pytest.raises(ValueError):
        ScheduleState.from_json(text)
