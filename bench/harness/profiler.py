"""Sampling the node with py-spy while it works, and reading the samples back."""

import contextlib
import shutil
import signal
import subprocess
import sys
import threading
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

START_TIMEOUT_SEC = 10.0
STOP_TIMEOUT_SEC = 30.0
SAMPLING_RATE_HZ = 400
# Only samples of a thread holding the GIL: the node's Python work. Without it, this machine's
# py-spy also counted threads blocked in a wait (rcl_wait, a queue, sigwait) as busy: a node
# using 1.2-3 % of a core while 1,000 tasks waited showed 186-241 samples in 5 s, 30 with it.
# DDS work done with the GIL released (rclpy's publish, beyond serializing) is not in it.


def py_spy_executable() -> str:
    beside_python = Path(sys.executable).with_name('py-spy')
    return str(beside_python) if beside_python.exists() else shutil.which('py-spy') or ''


# (area, markers): a sample belongs to the first area one of whose markers is in any frame
SPECIFIC_AREAS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ('rclpy logging (caller lookup, realpath) of log lines', ('RcutilsLogger.',)),
    ('numpy printing of goal ids in rclpy action debug lines', ('numpy/',)),
    ("walking an action waitable's futures (_set_executor)", ('Future._set_executor',)),
    ("removing from an action waitable's futures", ('Waitable.remove_future',)),
    ('building + publishing active_tasks', ('publish_active',)),
    ('building + publishing results', ('publish_result',)),
    ('task events: rate limit, build + publish', ('task_events.py', 'feedback_rate.py')),
    ('JSON <-> message conversion', ('json_codec.py',)),
)
# otherwise: the area of the innermost frame that has one of these markers
GENERIC_AREAS: tuple[tuple[str, tuple[str, ...]], ...] = (
    (
        'other Task Manager code',
        ('task_manager/core/', 'task_manager/ros/', 'task_manager/messages/'),
    ),
    ('rclpy actions, other', ('rclpy/action/',)),
    ('rclpy executor loop (pending tasks, wait sets)', ('rclpy/',)),
)
NODE_ENTRY_POINT = 'task_manager/ros/node_process.py'
# a thread blocked in sigwait (waiting for a shutdown signal) is idle, but py-spy counts it
IDLE_LEAF = 'sigwait ('


def area_of(frames: tuple[str, ...]) -> str:
    """Where a sample's time goes, by the frames on its stack (the leaf last)."""
    for area, markers in SPECIFIC_AREAS:
        if any(marker in frame for frame in frames for marker in markers):
            return area
    for frame in reversed(frames):
        if NODE_ENTRY_POINT in frame:
            continue
        for area, markers in GENERIC_AREAS:
            if any(marker in frame for marker in markers):
                return area
    return 'other'


@dataclass(frozen=True)
class Profile:
    """Samples of the node's Python stacks; a frame reads `name (file:first line)`."""

    # key: stack (outermost frame first), value: samples of it
    stacks: Counter[tuple[str, ...]]

    @classmethod
    def parse(cls, collapsed: str) -> 'Profile':
        """Read py-spy's raw (collapsed stacks) output: `frame;frame;... count` per line.

        Samples of a thread blocked in sigwait are left out: they are idle.
        """
        stacks: Counter[tuple[str, ...]] = Counter()
        for line in collapsed.splitlines():
            stack, _, count_text = line.rpartition(' ')
            frames = tuple(stack.split(';'))
            if stack and count_text.isdigit() and not frames[-1].startswith(IDLE_LEAF):
                stacks[frames] += int(count_text)
        return cls(stacks)

    @property
    def samples(self) -> int:
        return sum(self.stacks.values())

    def share(self, samples: int) -> float:
        return samples / self.samples if self.samples else 0.0

    def self_samples(self) -> Counter[str]:
        """Samples per function at the top of the stack."""
        counts: Counter[str] = Counter()
        for frames, count in self.stacks.items():
            counts[frames[-1]] += count
        return counts

    def node_inclusive_samples(self) -> Counter[str]:
        """Samples per function of the node's own code anywhere on the stack."""
        counts: Counter[str] = Counter()
        for frames, count in self.stacks.items():
            for frame in set(frames):
                if 'task_manager/' in frame and NODE_ENTRY_POINT not in frame:
                    counts[frame] += count
        return counts

    def areas(self) -> Counter[str]:
        counts: Counter[str] = Counter()
        for frames, count in self.stacks.items():
            counts[area_of(frames)] += count
        return counts


class PySpyRecorder:
    """`py-spy record` attached to a running process, stopped with SIGINT.

    A recording that fails leaves the body unprofiled and says why in `failure`.
    """

    def __init__(self, output: Path) -> None:
        self.output = output
        self.failure = ''

    def _command(self, pid: int) -> list[str]:
        return [
            py_spy_executable(),
            'record',
            '--pid',
            str(pid),
            '--rate',
            str(SAMPLING_RATE_HZ),
            '--format',
            'raw',
            '--function',
            '--gil',
            '--output',
            str(self.output),
        ]

    @contextlib.contextmanager
    def recording(self, pid: int) -> Iterator[None]:
        process = subprocess.Popen(
            self._command(pid), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        )
        sampling = threading.Event()
        reader = threading.Thread(target=_watch, args=(process, sampling), daemon=True)
        reader.start()
        if not sampling.wait(START_TIMEOUT_SEC):
            self.failure = f'py-spy did not start sampling pid {pid} within {START_TIMEOUT_SEC} s'
        try:
            yield
        finally:
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
            try:
                process.wait(STOP_TIMEOUT_SEC)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(STOP_TIMEOUT_SEC)
                self.failure = self.failure or 'py-spy did not stop on SIGINT'
            reader.join(STOP_TIMEOUT_SEC)

    def profile(self) -> Profile | None:
        """The samples recorded, or None if the recording failed."""
        if self.failure or not self.output.exists():
            self.failure = self.failure or 'py-spy wrote no output'
            return None
        return Profile.parse(self.output.read_text())


def _watch(process: subprocess.Popen[str], sampling: threading.Event) -> None:
    """Drain py-spy's output; signal once it says it is sampling."""
    assert process.stdout is not None
    for line in process.stdout:
        if 'Sampling process' in line:
            sampling.set()
