"""A watchdog on the DDS middleware under the Task Manager's process (no rclpy here).

Fast DDS 3.2 can deadlock between its timer thread (`dds.ev.<n>`) and a receive thread when a
remote writer is removed while an announcement fires (eProsima/Fast-DDS#6502, open; no newer
Fast DDS in the registry). No thread of ours is in the cycle: the node looks alive, but hears
no one and no one hears it, and the tasks it runs never end. The timer thread wakes at least at
each of the participant's announcements (each second with fastdds_discovery.xml, each 3 s with
Fast DDS's defaults), so it yields the CPU at least that often: one that has not for
`timeout_sec` is stuck. The watchdog then says so in one line and ends the process, for its
supervisor to start it again (the history is written as each task ends, so a restarted node
ends the tasks that were running, `ERROR`, and forgets nothing).

The watchdog reads `/proc` from a thread of its own: the executor's thread, blocked in a call
into the middleware, could not. That thread needs the interpreter, which a thread blocked in C
without releasing it would hold: each round also pushes back faulthandler's own timer (a thread
in C), which ends the process with every thread's stack if the rounds stop. A process that
was stopped (SIGSTOP, a debugger) starts counting again when it runs; faulthandler's timer does
not know that: debug the node with `middleware_watchdog_timeout: 0`.
"""

import contextlib
import faulthandler
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path

TIMER_THREAD_PREFIX = 'dds.ev.'
"""Fast DDS's name for a participant's timer thread (`dds.ev.<participant id>`)."""
SHORTEST_TIMEOUT_SEC = 1.0
LONGEST_TIMEOUT_SEC = 3600.0
"""The bounds of the node's `middleware_watchdog_timeout` (0 turns the watchdog off)."""
ROUNDS_PER_TIMEOUT = 6
"""How often the threads are read within a timeout."""
INTERPRETER_GRACE_SEC = 30.0
"""How long after the timeout faulthandler ends a process whose watchdog stopped running."""

TaskSwitches = dict[int, int]
"""key: thread id, value: its voluntary context switches so far."""


def timer_threads(process: Path = Path('/proc/self')) -> TaskSwitches:
    """The middleware's timer threads in `process` and how often each has yielded the CPU."""
    found: TaskSwitches = {}
    for task in (process / 'task').iterdir():
        try:
            if not (task / 'comm').read_text().startswith(TIMER_THREAD_PREFIX):
                continue
            status = (task / 'status').read_text()
        except OSError:  # the thread ended meanwhile
            continue
        for line in status.splitlines():
            if line.startswith('voluntary_ctxt_switches:'):
                found[int(task.name)] = int(line.split()[1])
    return found


class StallClock:
    """Since when each thread has not yielded the CPU; a thread first seen counts from then."""

    def __init__(self) -> None:
        # key: thread id, value: (switches last seen, when they last changed)
        self._seen: dict[int, tuple[int, float]] = {}

    def observe(self, switches: TaskSwitches, now: float) -> tuple[int, float] | None:
        """Take a reading; the thread that has not yielded for longest and for how long."""
        seen: dict[int, tuple[int, float]] = {}
        for tid, count in switches.items():
            last = self._seen.get(tid)
            seen[tid] = last if last is not None and last[0] == count else (count, now)
        self._seen = seen
        if not seen:
            return None
        tid, (_, since) = min(seen.items(), key=lambda item: item[1][1])
        return tid, now - since


class MiddlewareWatchdog:
    """Calls `on_stuck(message)` once when a timer thread has not run for `timeout_sec`."""

    def __init__(
        self,
        timeout_sec: float,
        on_stuck: Callable[[str], None],
        read: Callable[[], TaskSwitches] = timer_threads,
    ) -> None:
        self._timeout_sec = timeout_sec
        self._on_stuck = on_stuck
        self._read = read
        self._clock = StallClock()
        self._stopped = threading.Event()
        self._thread = threading.Thread(target=self._watch, name='middleware-watchdog', daemon=True)

    def start(self) -> None:
        self._arm_faulthandler()
        self._thread.start()

    def stop(self) -> None:
        self._stopped.set()
        self._thread.join()
        faulthandler.cancel_dump_traceback_later()

    def _arm_faulthandler(self) -> None:
        """End the process if no round follows within the timeout and grace (not without a
        standard error to print the stacks on)."""
        with contextlib.suppress(RuntimeError, ValueError):  # sys.stderr None or closed
            faulthandler.dump_traceback_later(self._timeout_sec + INTERPRETER_GRACE_SEC, exit=True)

    def _watch(self) -> None:
        period_sec = self._timeout_sec / ROUNDS_PER_TIMEOUT
        last_round = time.monotonic()
        while not self._stopped.wait(period_sec):
            self._arm_faulthandler()
            now = time.monotonic()
            if now - last_round > 2 * period_sec:  # the process was stopped (SIGSTOP, a
                self._clock = StallClock()  # debugger) or starved: no thread could run
            last_round = now
            try:
                switches = self._read()
            except OSError:  # no /proc: nothing to watch, and the rounds go on
                switches = {}
            stalled = self._clock.observe(switches, now)
            if stalled is not None and stalled[1] >= self._timeout_sec:
                tid, stalled_sec = stalled
                self._on_stuck(
                    f'the DDS middleware is stuck: its timer thread (thread {tid} of process '
                    f'{os.getpid()}) has not run for {stalled_sec:.1f} s (a Fast DDS deadlock, '
                    'eProsima/Fast-DDS#6502); exiting so that a supervisor starts the node again'
                )
                return
