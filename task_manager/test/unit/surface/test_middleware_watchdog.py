"""The middleware watchdog: Fast DDS's timer thread found by its name, a stall measured in its
context switches, the process told once; and faulthandler's timer ending a process whose
interpreter is held. Stand-ins for the threads (the real one: test_middleware_faults.py)."""

import subprocess
import sys
import textwrap
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from task_manager.middleware_watchdog import (
    MiddlewareWatchdog,
    StallClock,
    TaskSwitches,
    timer_threads,
)

TIMEOUT_SEC = 5.0
WATCHDOG_TIMEOUT_SEC = 0.3
TICKS = 100


class NamedThread:
    """A thread with a native name that yields the CPU each time it is ticked."""

    def __init__(self, name: str) -> None:
        self._tick = threading.Event()
        self._ticked = threading.Event()
        self._stopped = False
        named = threading.Event()
        self.native_id = 0

        def run() -> None:
            self.native_id = threading.get_native_id()
            Path(f'/proc/self/task/{self.native_id}/comm').write_text(name)
            named.set()
            while not self._stopped:
                self._tick.wait()
                self._tick.clear()
                self._ticked.set()

        self._thread = threading.Thread(target=run, daemon=True)
        self._thread.start()
        assert named.wait(TIMEOUT_SEC)

    def tick(self) -> None:
        self._ticked.clear()
        self._tick.set()
        assert self._ticked.wait(TIMEOUT_SEC)

    def stop(self) -> None:
        self._stopped = True
        self._tick.set()
        self._thread.join(TIMEOUT_SEC)


@pytest.fixture
def timer_thread() -> Iterator[NamedThread]:
    thread = NamedThread('dds.ev.7')
    yield thread
    thread.stop()


def test_the_timer_thread_is_found_by_name_and_its_switches_counted(
    timer_thread: NamedThread,
) -> None:
    other = NamedThread('dds.udp.7400')
    try:
        before = timer_threads()
        assert timer_thread.native_id in before
        assert other.native_id not in before
        for _ in range(TICKS):  # a tick may find it still running, not yet blocked again
            timer_thread.tick()
            if timer_threads()[timer_thread.native_id] > before[timer_thread.native_id]:
                break
        else:
            pytest.fail(f'no context switch of the timer thread counted in {TICKS} ticks')
    finally:
        other.stop()


def test_the_stall_clock_counts_from_the_last_change_of_each_thread() -> None:
    clock = StallClock()
    assert clock.observe({}, 0.0) is None
    assert clock.observe({1: 5}, 0.0) == (1, 0.0)
    assert clock.observe({1: 5, 2: 9}, 10.0) == (1, 10.0)  # 2 counts from when first seen
    assert clock.observe({1: 6, 2: 9}, 12.0) == (2, 2.0)
    assert clock.observe({1: 6}, 15.0) == (1, 3.0)  # a thread gone is forgotten


def _watch(
    read: Callable[[], TaskSwitches],
) -> tuple[MiddlewareWatchdog, list[str], threading.Event]:
    told: list[str] = []
    stuck = threading.Event()

    def on_stuck(message: str) -> None:
        told.append(message)
        stuck.set()

    watchdog = MiddlewareWatchdog(WATCHDOG_TIMEOUT_SEC, on_stuck, read)
    watchdog.start()
    return watchdog, told, stuck


def test_a_thread_that_stops_running_is_told_once() -> None:
    watchdog, told, stuck = _watch(lambda: {42: 5})
    try:
        assert stuck.wait(TIMEOUT_SEC)
        assert not threading.Event().wait(3 * WATCHDOG_TIMEOUT_SEC) and len(told) == 1
    finally:
        watchdog.stop()
    assert 'the DDS middleware is stuck: its timer thread (thread 42 of process' in told[0]
    assert 'eProsima/Fast-DDS#6502' in told[0]


def test_a_running_thread_or_none_at_all_is_left_alone() -> None:
    switches = iter(range(1_000_000))
    for read in (lambda: {42: next(switches)}, dict):
        watchdog, told, stuck = _watch(read)
        try:
            assert not stuck.wait(4 * WATCHDOG_TIMEOUT_SEC)
        finally:
            watchdog.stop()
        assert told == []


def test_a_held_interpreter_ends_the_process_with_its_stacks() -> None:
    script = textwrap.dedent(
        """
        import re
        from task_manager import middleware_watchdog

        middleware_watchdog.INTERPRETER_GRACE_SEC = 0.5
        middleware_watchdog.MiddlewareWatchdog(0.3, print).start()

        def hold_the_interpreter():  # backtracking in C, which never lets the GIL go
            re.match(r'(a+)+$', 'a' * 64 + 'b')

        hold_the_interpreter()
        """
    )
    ended = subprocess.run(
        [sys.executable, '-c', script], capture_output=True, text=True, timeout=30, check=False
    )
    assert ended.returncode == 1
    assert 'Timeout' in ended.stderr
    assert 'hold_the_interpreter' in ended.stderr


def test_without_proc_the_rounds_go_on() -> None:
    """A round that cannot read /proc finds nothing to watch; the next rounds still come (they
    keep faulthandler's timer from ending the process)."""
    reads: list[float] = []
    rounds = threading.Event()

    def no_proc() -> dict[int, int]:
        reads.append(0.0)
        if len(reads) >= 3:
            rounds.set()
        raise FileNotFoundError('/proc/self/task')

    watchdog, told, _ = _watch(no_proc)
    try:
        assert rounds.wait(TIMEOUT_SEC)
    finally:
        watchdog.stop()
    assert told == []
