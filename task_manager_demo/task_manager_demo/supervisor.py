"""Supervising the children of a launcher (`task-manager-demo`, `task-manager-fleet`).

The children are started, each with the log line that says it is ready; the launcher waits
(bounded) for all of them, then streams their logs until a signal or a child's exit, and
stops them in the reverse order of their start (SIGINT, a bounded wait, a kill as a last
resort). A child that exits with code 3 asks to be started again (the node whose middleware
is stuck, a gateway that no longer hears its node after a hold-up): it is, up to
MAX_RESTARTS times. Everything arrives through one event queue, so the main thread never polls.
"""

import argparse
import contextlib
import queue
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from task_manager.discovery import use_quick_discovery
from task_manager.process_setup import EXIT_START_AGAIN
from task_manager_demo.children import (
    Child,
    Event,
    Events,
    Exited,
    Line,
    Signalled,
    forward_stop_signals,
)

STOP_TIMEOUT_SEC = 10.0
EXIT_FAILED = 1
MAX_RESTARTS = 5
"""A child started again more often than this fails the launcher (something else is wrong)."""
# Colour codes of ROS log lines, when the children log in colour (on a terminal).
COLOUR_CODE = re.compile(r'\x1b\[[0-9;]*m')


@dataclass(frozen=True)
class _Later:
    """A child to start once the children it needs are ready."""

    name: str
    command: list[str]
    ready: re.Pattern[str]
    env: dict[str, str] | None
    needs: tuple[Child, ...]


def say(text: str) -> None:
    # OSError: the terminal is gone (its window was closed); the launcher goes on stopping.
    with contextlib.suppress(OSError):
        print(text, flush=True)


class Supervisor:
    """Subclasses start their children in `start` and say what to try in `banner`."""

    def __init__(self, events: Events, prefix_lines: bool = False) -> None:
        """`prefix_lines`: stream each log line as `[child] line`."""
        self.events = events
        self.children: list[Child] = []
        self.streaming = False
        self._prefix_lines = prefix_lines
        self._ready: dict[Child, re.Pattern[str]] = {}
        self._later: list[_Later] = []
        self._restarts = 0

    def start_child(
        self,
        name: str,
        command: list[str],
        ready: re.Pattern[str],
        env: dict[str, str] | None = None,
    ) -> Child:
        """Start a child; `ready`: its log line that says it is ready (named groups kept)."""
        child = Child(name, command, self.events, env=env)
        self.children.append(child)
        self._ready[child] = ready
        return child

    def start_when_ready(
        self,
        name: str,
        command: list[str],
        ready: re.Pattern[str],
        needs: Sequence[Child],
        env: dict[str, str] | None = None,
    ) -> None:
        """Start a child once each child of `needs` is ready (as `start_child` does then);
        never, if one of them fails or a signal comes first."""
        self._later.append(_Later(name, command, ready, env, tuple(needs)))

    def start(self) -> None:
        raise NotImplementedError

    def banner(self, ready: dict[str, str]) -> str:
        """What is printed once every child is ready (`ready`: their ready lines' groups)."""
        raise NotImplementedError

    def run(self, ready_timeout_sec: float) -> int:
        """Wait for the children to be ready, then until a signal; the exit code."""
        ready = self.wait_ready(ready_timeout_sec)
        if ready is None:
            return EXIT_FAILED
        if not ready:
            return 0
        say(self.banner(ready))
        return self.follow()

    def wait_ready(self, timeout_sec: float) -> dict[str, str] | None:
        """The named groups of the ready lines; {} when stopped by a signal first; None on a
        failure (a child not ready in time, or gone: its output is shown)."""
        deadline = time.monotonic() + timeout_sec
        waiting = dict(self._ready)
        details: dict[str, str] = {}
        while waiting or self._later:
            self._start_later(waiting)
            event = self._next(deadline)
            if event is None:
                self._report(list(waiting), 'was not ready in time')
                return None
            if isinstance(event, Signalled):
                return {}
            if isinstance(event, Exited):
                code = event.child.wait(STOP_TIMEOUT_SEC)
                self._report([event.child], f'exited with code {code} before it was ready')
                return None
            pattern = waiting.get(event.child)
            match = pattern.search(COLOUR_CODE.sub('', event.text)) if pattern else None
            if match:
                details.update(match.groupdict())
                del waiting[event.child]
        return details

    def _start_later(self, waiting: dict[Child, re.Pattern[str]]) -> None:
        """Start the children whose needs are all ready (no longer `waiting`)."""
        for later in [lat for lat in self._later if not waiting.keys() & set(lat.needs)]:
            self._later.remove(later)
            child = self.start_child(later.name, later.command, later.ready, later.env)
            waiting[child] = later.ready

    def follow(self) -> int:
        """Stream the children's logs until a signal (0) or a child's exit (failure)."""
        self.streaming = True
        while True:
            event = self.events.get()
            if isinstance(event, Signalled):
                return 0
            if isinstance(event, Line):
                self._say_line(event)
            else:
                code = event.child.wait(STOP_TIMEOUT_SEC)
                if code == EXIT_START_AGAIN and self._restarts < MAX_RESTARTS:
                    self._restarts += 1
                    say(f'{event.child.name} exited with code {code}: starting it again')
                    self._start_again(event.child)
                    continue
                say(f'{event.child.name} exited unexpectedly with code {code}')
                return EXIT_FAILED

    def _start_again(self, child: Child) -> None:
        """A new process of `child`, in its place (its turn to stop stays the same)."""
        again = Child(child.name, child.command, self.events, env=child.env)
        self.children[self.children.index(child)] = again
        self._ready[again] = self._ready.pop(child)

    def stop(self) -> bool:
        """Stop the children, the last started first; True when each stopped by itself."""
        return all([self._stop(child) for child in reversed(self.children)])

    def _stop(self, child: Child) -> bool:
        """SIGINT, a bounded wait (a further Ctrl-C is passed on), a kill as a last resort."""
        child.interrupt()
        deadline = time.monotonic() + STOP_TIMEOUT_SEC
        while child.output_open:
            event = self._next(deadline)
            if event is None:
                break
            if isinstance(event, Signalled):
                child.interrupt()
            elif isinstance(event, Line) and self.streaming:
                self._say_line(event)
        if child.wait(deadline - time.monotonic()) is None:
            say(f'{child.name} did not stop within {STOP_TIMEOUT_SEC} s: killing it')
            child.kill()
            return False
        return True

    def _say_line(self, line: Line) -> None:
        say(f'[{line.child.name}] {line.text}' if self._prefix_lines else line.text)

    def _next(self, deadline: float) -> Event | None:
        try:
            return self.events.get(timeout=max(deadline - time.monotonic(), 0.0))
        except queue.Empty:
            return None

    @staticmethod
    def _report(children: list[Child], state: str) -> None:
        for child in children:
            say(f'{child.name} {state}; its output:')
            say('\n'.join(f'  {line}' for line in child.output) or '  (none)')


def supervise_demo(
    demo: Callable[[argparse.Namespace, Events], Supervisor],
    options: argparse.Namespace,
    stopped: str,
) -> int:
    """`supervise` the supervisor `demo(options, events)` (options.ready_timeout: how long its
    children may take to be ready), with the project's quick discovery for it and its
    children, which inherit the environment."""
    use_quick_discovery()
    return supervise(lambda events: demo(options, events), options.ready_timeout, stopped)


def supervise(make: Callable[[Events], Supervisor], ready_timeout_sec: float, stopped: str) -> int:
    """Start, run and stop the supervisor `make(events)` gives; `stopped` said after a clean
    stop. The exit code: 0, or EXIT_FAILED when a child failed or did not stop by itself."""
    events: Events = queue.SimpleQueue()
    forward_stop_signals(events)
    supervisor = make(events)
    try:
        supervisor.start()
        code = supervisor.run(ready_timeout_sec)
    finally:
        stopped_cleanly = supervisor.stop()
    if not stopped_cleanly:
        return EXIT_FAILED
    if code == 0:
        say(stopped)
    return code
