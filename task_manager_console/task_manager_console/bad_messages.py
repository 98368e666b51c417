"""What the console does with a robot's message it cannot use: count it, and log it at most
once per robot per minute (a robot sending garbage in a loop must not flood the log)."""

import logging
import threading
import time
from collections.abc import Callable

from task_manager.core.text.request_text import loggable

LOG_INTERVAL_SEC = 60.0


class BadMessages:
    """The count of bad messages, in all and per robot; one log line per robot per minute."""

    def __init__(self, log: logging.Logger, clock: Callable[[], float] = time.monotonic) -> None:
        self.total = 0
        self.per_robot: dict[str, int] = {}
        """Key: robot id (as sent, maybe unusable), value: its bad messages."""
        self._log = log
        self._clock = clock
        # key: robot id, value: when its last line was logged (clock's seconds)
        self._logged: dict[str, float] = {}
        self._lock = threading.Lock()

    def count(self, robot_id: str, topic: str, why: str) -> int:
        """Count one bad message of `robot_id` on its `topic`; the robot's count so far."""
        now = self._clock()
        with self._lock:
            self.total += 1
            count = self.per_robot[robot_id] = self.per_robot.get(robot_id, 0) + 1
            last = self._logged.get(robot_id)
            due = last is None or now - last >= LOG_INTERVAL_SEC
            if due:
                self._logged[robot_id] = now
        if due:
            self._log.warning(
                'robot %s: a message on %s ignored (%d so far; logged at most once a minute): %s',
                loggable(robot_id),
                topic,
                count,
                loggable(why, 300),
            )
        return count
