"""FeedbackGate: at most one feedback per interval per task, the latest wins."""

import itertools

from hypothesis import given
from hypothesis import strategies as st

from task_manager.core.feedback_rate import FeedbackAction, FeedbackGate

INTERVAL = 0.1  # 10 Hz


def test_the_first_feedback_goes_out_at_once() -> None:
    assert FeedbackGate(INTERVAL).offer(5.0) is FeedbackAction.SEND


def test_feedback_within_the_interval_is_held_once_and_replaced_after() -> None:
    gate = FeedbackGate(INTERVAL)
    gate.offer(5.0)

    assert gate.offer(5.02) is FeedbackAction.HOLD
    assert abs(gate.delay_until_slot(5.02) - 0.08) < 1e-9
    assert gate.offer(5.05) is FeedbackAction.REPLACE_HELD
    assert gate.release(5.1) is True
    assert gate.offer(5.15) is FeedbackAction.HOLD  # the slot after the release


def test_after_a_quiet_interval_feedback_goes_out_at_once() -> None:
    gate = FeedbackGate(INTERVAL)
    gate.offer(5.0)

    assert gate.offer(5.25) is FeedbackAction.SEND
    assert gate.release(5.3) is False  # nothing held: nothing to send at the end


@given(st.lists(st.floats(min_value=0.0, max_value=0.05), min_size=1, max_size=200))
def test_sent_feedback_is_never_closer_than_the_interval(gaps: list[float]) -> None:
    """Whatever the arrival times, what goes out (at once or at its slot) is spaced."""
    gate = FeedbackGate(INTERVAL)
    now, sent, slot = 0.0, [], None
    for gap in gaps:
        now += gap
        if slot is not None and now >= slot:
            gate.release(slot)
            sent.append(slot)
            slot = None
        action = gate.offer(now)
        if action is FeedbackAction.SEND:
            sent.append(now)
        elif action is FeedbackAction.HOLD:
            slot = now + gate.delay_until_slot(now)

    assert all(b - a >= INTERVAL - 1e-9 for a, b in itertools.pairwise(sent))
