"""A process's output, read line by line in a thread as it comes, to wait on.

No rclpy here: the fleet console's tests, which are cloud-side, read their processes with it too.
"""

import re
import threading
from typing import IO


class OutputReader:
    """The lines of `stream` (a process's text output), read in a thread until it ends."""

    def __init__(self, stream: IO[str]) -> None:
        self.lines: list[str] = []
        """Every line read so far, without its line break."""
        self.ended = False
        """Whether the output has ended (the process closed it, or exited)."""
        self._changed = threading.Condition()
        self._thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._thread.start()

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            with self._changed:
                self.lines.append(line.rstrip('\n'))
                self._changed.notify_all()
        with self._changed:
            self.ended = True
            self._changed.notify_all()

    def find(self, pattern: str, timeout_sec: float) -> str | None:
        """The first line matching the regular expression `pattern`, waited for at most
        `timeout_sec`; None when the output ended without it or the time passed (`ended` says
        which)."""
        regex = re.compile(pattern)

        def found() -> tuple[str | None] | None:
            """(the line,) once found, (None,) once the output has ended without it, else None."""
            line = next((line for line in self.lines if regex.search(line)), None)
            return (line,) if line is not None or self.ended else None

        with self._changed:
            outcome = self._changed.wait_for(found, timeout_sec)
        return outcome[0] if outcome else None

    def join(self, timeout_sec: float) -> None:
        """Wait at most `timeout_sec` for the output to end and be read."""
        self._thread.join(timeout_sec)
