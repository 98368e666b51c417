"""How long the schedules' one timer is set for: a little short of the next due time, then
again for what is left.

A timer's wait ends late by a share of its length where the machine's wake-ups are coarse: on
the 2-core VM of the benchmarks an rcl timer set for 1 s rang 5-14 ms late, for 3 s 23-26 ms,
for 10 s 38-41 ms (Python's `threading.Event.wait(10)` 12 ms, `time.sleep(10)` 6 ms). Set for
the due time itself, the first run of a schedule started that late, after a quiet spell. Set
EARLY_SHARE of its length short, it rings a little early; the scheduler finds nothing due yet
and sets it again for the rest, which is short, so late by little: two or three rings per due
time, the last within a millisecond or so.
"""

EARLY_SHARE = 0.02
"""How much of a wait the timer is set short by: more than the lateness measured (1.3 %)."""
EXACT_WITHIN_SEC = 0.05
"""A due time closer than this is waited for exactly (a wait this short is late by < 1 ms)."""
MIN_TIMER_SEC = 0.001
MAX_TIMER_SEC = 300.0
"""The longest wait, so that a wall clock that jumped forward is noticed soon."""


def timer_delay(until_due_sec: float) -> float:
    """The delay to set the timer for, the next due time `until_due_sec` from now (negative:
    due already): never past the due time, at least MIN_TIMER_SEC, at most MAX_TIMER_SEC."""
    if until_due_sec <= EXACT_WITHIN_SEC:
        return max(until_due_sec, MIN_TIMER_SEC)
    return min(until_due_sec * (1 - EARLY_SHARE), MAX_TIMER_SEC)
