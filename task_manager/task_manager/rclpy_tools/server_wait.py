"""Waiting until DDS has matched a client with its server.

rclpy's `wait_for_service` and `ActionClient.wait_for_server` look every 0.25 s (rclpy issue
#58: no graph event reaches Python). A server is usually matched within a few milliseconds of
the client's creation (or of the server's start), so each such wait cost a command line or a
gateway about 0.1-0.25 s for nothing. This looks every millisecond at first, then at most every
20 ms: a look costs microseconds, a 5 s wait for a missing server 250 of them.
"""

from collections.abc import Callable
from time import monotonic, sleep

FIRST_LOOK_AFTER_SEC = 0.001
LONGEST_GAP_SEC = 0.02


def wait_until_ready(is_ready: Callable[[], bool], timeout_sec: float) -> bool:
    """Wait (bounded) until `is_ready()`, e.g. a client's `service_is_ready`; whether it is."""
    deadline = monotonic() + timeout_sec
    gap_sec = FIRST_LOOK_AFTER_SEC
    while not is_ready():
        remaining_sec = deadline - monotonic()
        if remaining_sec <= 0:
            return is_ready()
        sleep(min(gap_sec, remaining_sec))
        gap_sec = min(gap_sec * 2, LONGEST_GAP_SEC)
    return True
