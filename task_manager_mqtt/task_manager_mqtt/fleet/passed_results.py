"""Which results of one robot were passed on, so that each is passed on once.

A result is known by its sequence number in the robot's history and its task's id. One
delivered again (after a reconnection: the broker's messages in flight, the bridge's results not
yet acknowledged) comes with both as before. A robot whose history began again (a new history
file: the robot reinstalled, its history moved) sends sequence numbers it sent before, with
other tasks: those are new results, and were dropped when every result at or below the last
sequence counted as a duplicate. So a result is a duplicate when its sequence came with the
same task id, among the robot's last RECENT_RESULTS sequence numbers: a ring indexed by the
sequence, one 8-byte hash of (sequence, task id) a slot, 32 KiB a robot.
"""

from array import array

RECENT_RESULTS = 4096
"""More than the results delivered again at a reconnection: the bridge keeps at most 200 in
flight, a broker at most its in-flight window to a client (mosquitto: 20 by default)."""


class PassedResults:
    """The recent results of one robot passed on (not thread-safe: the receiver's lock)."""

    def __init__(self) -> None:
        self._ring = array('q', bytes(8 * RECENT_RESULTS))

    def first_time(self, sequence: int, task_id: str) -> bool:
        """Whether this result was not passed on among the recent ones; it is then counted as
        passed on."""
        slot = sequence % RECENT_RESULTS
        key = hash((sequence, task_id)) or 1  # 0 marks a slot never used
        if self._ring[slot] == key:
            return False
        self._ring[slot] = key
        return True
