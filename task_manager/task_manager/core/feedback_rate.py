"""At most N feedback updates per second per task; the latest wins, none is queued.

A server may publish feedback at 50 Hz or more; subscribers of the task events need a few
updates a second. A FeedbackGate decides, for one task, whether a new feedback goes out now
or is held until its slot. Only whether something is held is kept, not what: when the slot
comes, the task's latest feedback goes out, so stale feedback is never sent.
"""

import enum
from dataclasses import dataclass


class FeedbackAction(enum.Enum):
    SEND = 'send'
    """Send it now."""
    HOLD = 'hold'
    """Hold it: arm a timer for `delay_until_slot`, then `release`."""
    REPLACE_HELD = 'replace_held'
    """It replaces the feedback already held; the timer armed for that one sends it."""


@dataclass
class FeedbackGate:
    """The feedback rate limit of one task."""

    min_interval_sec: float
    last_sent_at: float | None = None
    held: bool = False

    def offer(self, now: float) -> FeedbackAction:
        """What to do with a feedback that arrives at `now`."""
        if self.held:
            return FeedbackAction.REPLACE_HELD
        if self.last_sent_at is None or now - self.last_sent_at >= self.min_interval_sec:
            self.last_sent_at = now
            return FeedbackAction.SEND
        self.held = True
        return FeedbackAction.HOLD

    def delay_until_slot(self, now: float) -> float:
        """Seconds until a held feedback may go out."""
        assert self.last_sent_at is not None
        return max(self.last_sent_at + self.min_interval_sec - now, 0.0)

    def release(self, now: float) -> bool:
        """The slot has come, or the task ends: True if a feedback was held (send it now)."""
        was_held = self.held
        self.held = False
        if was_held:
            self.last_sent_at = now
        return was_held
