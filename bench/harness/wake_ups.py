"""A process's CPU while it mostly waits, with how often its threads woke and what this machine
bills a wake-up.

Linux bills CPU time by sampling at its timer tick on many kernels (and VMs): a thread that
wakes from a sleep, even to do nothing, may be charged a whole tick. On the machine of
docs/benchmarks.md (a Firecracker VM) a Python thread sleeping 0.5 s at a time is billed
1.5 to 2.3 ms per wake-up, where it runs for microseconds. So a node whose own work is nothing
but whose middleware threads wake ten times a second shows 2 % of a core. The rows that
measure waiting report the wake-ups (voluntary context switches of all the process's threads)
and the machine's bill for one beside the CPU, so that a figure is read against its floor.
"""

import functools
import time
from dataclasses import dataclass
from pathlib import Path

import psutil

SLEEPER_PERIOD_SEC = 0.5
SLEEPER_WAKE_UPS = 8


def wake_ups(pid: int) -> int:
    """How often the threads of process `pid` have yielded the CPU so far (voluntary context
    switches, /proc), each a wait that ended."""
    total = 0
    for task in Path(f'/proc/{pid}/task').iterdir():
        try:
            status = (task / 'status').read_text()
        except OSError:  # the thread ended meanwhile
            continue
        for line in status.splitlines():
            if line.startswith('voluntary_ctxt_switches:'):
                total += int(line.split()[1])
    return total


@dataclass(frozen=True)
class CpuUse:
    """A process's CPU over an interval, in % of one core, and its threads' wake-ups a second."""

    percent: float
    wake_ups_per_sec: float


def cpu_use(pid: int, seconds: float) -> CpuUse:
    """The process's CPU time (user + system) over `seconds` of wall time and its wake-ups."""
    process = psutil.Process(pid)
    before, woke_before = process.cpu_times(), wake_ups(pid)
    time.sleep(seconds)  # the measured interval itself: nothing to wait for
    after, woke_after = process.cpu_times(), wake_ups(pid)
    used = (after.user - before.user) + (after.system - before.system)
    return CpuUse(100 * used / seconds, (woke_after - woke_before) / seconds)


@functools.cache
def billed_per_wake_up_ms() -> float:
    """What this machine bills a thread that sleeps SLEEPER_PERIOD_SEC and wakes to do nothing,
    in ms per wake-up (measured once per bench run, SLEEPER_WAKE_UPS times, in the calling
    thread: its own CPU time)."""
    started = time.thread_time()
    for _ in range(SLEEPER_WAKE_UPS):
        time.sleep(SLEEPER_PERIOD_SEC)  # the wake-ups are what is measured
    return (time.thread_time() - started) * 1000 / SLEEPER_WAKE_UPS


def wake_up_context(use: CpuUse) -> str:
    """The baseline column of a waiting row: the wake-ups and the machine's bill for each."""
    return (
        f'{use.wake_ups_per_sec:.1f} wake-ups/s; a sleeper here is billed '
        f'{billed_per_wake_up_ms():.2f} ms a wake-up'
    )
