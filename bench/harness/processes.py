"""Child processes of the bench: the node as users start it, and the bench's servers."""

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import psutil
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from task_manager.rclpy_tools.cleanup import destroy_waitables
from task_manager.testing.process import task_manager_executable

STOP_TIMEOUT_SEC = 10.0
REPO_ROOT = Path(__file__).resolve().parents[2]


class ChildProcess:
    """A process whose output goes to a log file (read by no thread of the bench)."""

    def __init__(self, name: str, command: list[str], log_dir: Path) -> None:
        self.name = name
        self.log_path = log_dir / f'{name}.log'
        with self.log_path.open('w') as log:
            self.process = subprocess.Popen(
                command, stdout=log, stderr=subprocess.STDOUT, cwd=REPO_ROOT
            )
        self.pid = self.process.pid

    def log_tail(self, lines: int = 20) -> str:
        return '\n'.join(self.log_path.read_text(errors='replace').splitlines()[-lines:])

    def stop(self) -> None:
        """SIGINT, then wait; kill only as a last resort (a kill leaves DDS files in /dev/shm)."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        try:
            self.process.wait(STOP_TIMEOUT_SEC)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(STOP_TIMEOUT_SEC)


def start_node(params_file: Path, log_dir: Path, name: str = 'task_manager') -> ChildProcess:
    command = [task_manager_executable(), '--ros-args', '--params-file', str(params_file)]
    return ChildProcess(name, command, log_dir)


def start_servers(log_dir: Path) -> ChildProcess:
    return ChildProcess('servers', [sys.executable, '-m', 'bench.harness.servers'], log_dir)


def start_relay(log_dir: Path) -> ChildProcess:
    return ChildProcess('relay', [sys.executable, '-m', 'bench.harness.relay'], log_dir)


def start_event_listener(log_dir: Path) -> ChildProcess:
    return ChildProcess(
        'event_listener', [sys.executable, '-m', 'bench.harness.event_listener'], log_dir
    )


def spin_child(
    node_name: str,
    build: Callable[[Node], object],
    executor_type: Callable[[], SingleThreadedExecutor] = SingleThreadedExecutor,
) -> None:
    """The main of a child process: a node with what `build` puts on it, spun until SIGINT."""
    rclpy.init()
    node = rclpy.create_node(node_name)
    executor = executor_type()
    build(node)
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        destroy_waitables(node)
        node.destroy_node()
        rclpy.try_shutdown()


class ResourceSampler:
    """Samples a process's thread count and RSS in a background thread, keeping the peaks."""

    def __init__(self, pid: int, period_sec: float = 0.05) -> None:
        self._process = psutil.Process(pid)
        self._period_sec = period_sec
        self._stop = threading.Event()
        self.peak_threads = 0
        self.peak_rss_bytes = 0
        self._thread = threading.Thread(target=self._run, name='resource-sampler', daemon=True)

    def sample(self) -> tuple[int, int]:
        """The process's thread count and RSS now."""
        with self._process.oneshot():
            return self._process.num_threads(), self._process.memory_info().rss

    def _run(self) -> None:
        while True:
            threads, rss = self.sample()
            self.peak_threads = max(self.peak_threads, threads)
            self.peak_rss_bytes = max(self.peak_rss_bytes, rss)
            if self._stop.wait(self._period_sec):
                return

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(STOP_TIMEOUT_SEC)


class OtherLoad:
    """CPU used by processes other than the bench's own, in cores, since it was created.

    Our processes are the bench and its children, running (the node, even a restarted one,
    the servers, py-spy) or ended (counted in the bench's children times once waited for);
    other developers' work on the machine shows up here.
    """

    def __init__(self) -> None:
        self._bench = psutil.Process(os.getpid())
        self._started = (time.perf_counter(), self._machine_busy_sec(), self._our_sec())

    @staticmethod
    def _machine_busy_sec() -> float:
        times = psutil.cpu_times()
        return sum(
            getattr(times, name, 0.0)
            for name in ('user', 'nice', 'system', 'irq', 'softirq', 'steal')
        )

    def _our_sec(self) -> float:
        total = 0.0
        for process in [self._bench, *self._bench.children(recursive=True)]:
            with contextlib.suppress(psutil.Error):
                times = process.cpu_times()
                total += times.user + times.system + times.children_user + times.children_system
        return total

    def cores(self) -> float:
        started_at, busy, ours = self._started
        elapsed_sec = time.perf_counter() - started_at
        others_sec = (self._machine_busy_sec() - busy) - (self._our_sec() - ours)
        return max(others_sec, 0.0) / elapsed_sec if elapsed_sec > 0 else 0.0


# What each of the bench's processes is, by a piece of its command line (the first that fits).
PROCESS_ROLES = (
    ('task-manager-web', 'web gateway'),
    ('task-manager-mqtt', 'MQTT bridge'),
    ('mosquitto', 'mosquitto'),
    ('stream_readers', 'event stream reader'),
    ('bench.harness.servers', 'servers'),
    ('task-manager ', 'node'),
)


def cpu_seconds_by_role() -> dict[str, float]:
    """CPU time (user + system) so far of the bench and each of its running children, by role
    (PROCESS_ROLES; 'bench' for the bench's own, with its clients and the FleetClient)."""
    bench = psutil.Process(os.getpid())
    used: dict[str, float] = {}
    for process in [bench, *bench.children(recursive=True)]:
        with contextlib.suppress(psutil.Error):
            command = ' '.join(process.cmdline())
            times = process.cpu_times()
            role = 'bench' if process.pid == bench.pid else _role(command)
            used[role] = used.get(role, 0.0) + times.user + times.system
    return used


def nice_by_role() -> dict[str, int]:
    """The nice value of each running child of the bench, by role (its main thread's)."""
    values: dict[str, int] = {}
    for process in psutil.Process(os.getpid()).children(recursive=True):
        with contextlib.suppress(psutil.Error):
            values[_role(' '.join(process.cmdline()))] = process.nice()
    return values


def _role(command: str) -> str:
    return next((role for piece, role in PROCESS_ROLES if piece in command), 'other')
