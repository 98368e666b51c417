"""Child processes of the demo launcher, whose output lines and exits arrive as events.

Every event goes into one queue that the launcher's main thread reads: a line of output, a
child's exit, or a signal to the launcher. The main thread thus waits on one thing, with a
bound, and never polls.
"""

import os
import queue
import signal
import subprocess
import sys
import threading
from dataclasses import dataclass
from pathlib import Path

from task_manager_demo.parent_death import die_with_parent

# SIGHUP: the terminal was closed, which stops the demo as Ctrl-C does.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


@dataclass(frozen=True)
class Line:
    child: 'Child'
    text: str


@dataclass(frozen=True)
class Exited:
    child: 'Child'


@dataclass(frozen=True)
class Signalled:
    signum: int


Event = Line | Exited | Signalled
Events = queue.SimpleQueue[Event]


def forward_stop_signals(events: Events) -> None:
    """Turn SIGINT, SIGTERM and SIGHUP to this process into Signalled events.

    SimpleQueue.put may be called from a signal handler (it is reentrant).
    """
    for signum in STOP_SIGNALS:
        signal.signal(signum, lambda received, _frame: events.put(Signalled(received)))


def child_environment() -> dict[str, str]:
    """Unbuffered logs, so every line arrives as soon as it is written; colours on a terminal."""
    env = dict(os.environ, RCUTILS_LOGGING_BUFFERED_STREAM='0', PYTHONUNBUFFERED='1')
    if sys.stdout.isatty():
        env.setdefault('RCUTILS_COLORIZED_OUTPUT', '1')
    return env


class Child:
    """A child process; its merged stdout and stderr are kept in `output` and queued as Lines.

    It runs in its own process group, so a terminal's Ctrl-C reaches only the launcher,
    which passes it on once (a second SIGINT may make a ROS node skip its clean shutdown).
    It gets SIGTERM when the launcher dies, however it dies, so it is never left behind.
    """

    def __init__(
        self,
        name: str,
        command: list[str],
        events: Events,
        cwd: Path | None = None,
        env: dict[str, str] | None = None,
    ) -> None:
        """`env`: added to the environment."""
        self.name = name
        self.command = command
        self.env = env
        self.output: list[str] = []
        self._events = events
        self.process = subprocess.Popen(
            die_with_parent(command),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env={**child_environment(), **(env or {})},
            cwd=cwd,
            process_group=0,
        )
        self._reader = threading.Thread(target=self._read, name=f'{name}-output', daemon=True)
        self._reader.start()

    def _read(self) -> None:
        # Signals must reach the main thread, whose blocking wait they interrupt.
        signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
        assert self.process.stdout is not None
        for raw in self.process.stdout:
            text = raw.rstrip('\n')
            self.output.append(text)
            self._events.put(Line(self, text))
        self._events.put(Exited(self))

    @property
    def output_open(self) -> bool:
        """False once the output has ended and the Exited event is queued."""
        return self._reader.is_alive()

    @property
    def exit_code(self) -> int | None:
        return self.process.poll()

    def interrupt(self) -> None:
        """Ask the child to stop as Ctrl-C does."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)

    def wait(self, timeout_sec: float) -> int | None:
        """The exit code, or None if the child is still running after `timeout_sec`."""
        try:
            code = self.process.wait(max(timeout_sec, 0.0))
        except subprocess.TimeoutExpired:
            return None
        self._reader.join(timeout_sec)
        return code

    def kill(self) -> int:
        """Last resort: a killed ROS process leaves Fast DDS files in /dev/shm."""
        self.process.kill()
        return self.process.wait()
