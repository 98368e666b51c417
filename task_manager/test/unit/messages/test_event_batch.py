"""The events of a turn gathered into messages: in order, none lost, within both bounds."""

from hypothesis import given
from hypothesis import strategies as st

from task_manager.core.event_batch import EventBatch

MAX_EVENTS = 5
MAX_BYTES = 100


def _messages(sizes: list[int]) -> list[list[int]]:
    """The messages a turn of events of these sizes makes (each event named by its index)."""
    batch = EventBatch[int](MAX_EVENTS, MAX_BYTES)
    messages = [full for index, size in enumerate(sizes) if (full := batch.add(index, size))]
    return [*messages, batch.take()] if len(batch) else messages


def test_a_turn_of_small_events_is_one_message() -> None:
    assert _messages([10, 10, 10]) == [[0, 1, 2]]


def test_the_events_beyond_max_events_go_in_the_next_message() -> None:
    assert _messages([1] * 12) == [[0, 1, 2, 3, 4], [5, 6, 7, 8, 9], [10, 11]]


def test_an_event_that_would_pass_max_bytes_starts_the_next_message() -> None:
    assert _messages([60, 40, 1, 99]) == [[0, 1], [2, 3]]


def test_an_event_larger_than_max_bytes_goes_alone() -> None:
    assert _messages([10, 250, 10]) == [[0], [1], [2]]


@given(st.lists(st.integers(min_value=0, max_value=3 * MAX_BYTES), max_size=60))
def test_every_event_goes_once_in_order_each_message_within_both_bounds(sizes: list[int]) -> None:
    messages = _messages(sizes)

    assert [event for message in messages for event in message] == list(range(len(sizes)))
    for message in messages:
        assert 0 < len(message) <= MAX_EVENTS
        assert len(message) == 1 or sum(sizes[event] for event in message) <= MAX_BYTES
