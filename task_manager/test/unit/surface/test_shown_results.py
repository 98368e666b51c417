"""taskctl results --follow's account of the results it showed (ShownResults): each result
once, whatever the order, and where to read the history from when events went missing."""

from hypothesis import given
from hypothesis import strategies as st

from task_manager.cli.verbs.watch import ABOVE_MAX, ShownResults


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
