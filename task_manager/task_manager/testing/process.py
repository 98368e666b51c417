"""Run the Task Manager as users do: a subprocess with a parameters file."""

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from task_manager.client.hearing import ANSWER_SEC, HELD_UP_SEC
from task_manager.cpu_priority import thread_ids
from task_manager.testing.harness import WaitTimeoutError
from task_manager.testing.native_stacks import every_thread
from task_manager.testing.output_reader import OutputReader

STOP_TIMEOUT_SEC = 10.0
ABORT_TIMEOUT_SEC = 5.0
SHARED_MEMORY_MARK = 'RTPS_TRANSPORT_SHM'
"""In Fast DDS's own lines about its shared-memory ports, which a process may print beside the
program's (see without_shared_memory_lines)."""
TASKCTL = str(Path(sys.executable).with_name('taskctl'))
TASKCTL_TIMEOUT_SEC = 30.0
TASKCTL_REACH_SEC = 15.0

# launch(tasks: {key: entry}, **node_parameters) -> a probe connected to the running node
LaunchTaskManager = Callable[..., Any]

TEST_NICENESS = 0
"""The nice value the tests start a gateway at: their own priority. The tests run beside each
other on a few cores, where a gateway yielding the CPU (task_manager.cpu_priority) would be
slowed by the other tests' nodes, not by its own work."""


def nice_option(nice: int | None) -> list[str]:
    """A gateway's `--nice` option for `nice` (None: none, the gateway's default)."""
    return [] if nice is None else ['--nice', str(nice)]


def thread_nice_values(pid: int) -> set[int]:
    """The nice values of the threads of process `pid` (on Linux a nice value is a thread's)."""
    values = set()
    for thread in thread_ids(pid):
        with contextlib.suppress(ProcessLookupError):  # a thread that ended meanwhile
            values.add(os.getpriority(os.PRIO_PROCESS, thread))
    return values


def task_manager_executable() -> str:
    """The `task-manager` console script of the running interpreter's environment."""
    beside_python = Path(sys.executable).with_name('task-manager')
    return str(beside_python) if beside_python.exists() else shutil.which('task-manager') or ''


def action_task(
    name: str, topic: str, interface: str = 'test_msgs.action.Fibonacci', **properties: Any
) -> dict[str, Any]:
    """A task entry for a parameters file, of an action task."""
    return {'task_name': name, 'topic': topic, 'msg_interface': interface, **properties}


def service_task(
    name: str, topic: str, interface: str = 'std_srvs/srv/SetBool', **properties: Any
) -> dict[str, Any]:
    """A task entry for a parameters file, of a service task."""
    return {'task_name': name, 'topic': topic, 'msg_interface': interface, **properties}


def write_params_file(path: Path, parameters: dict[str, Any]) -> Path:
    """Write `parameters` as the node's parameters file (`task_manager: ros__parameters:`)."""
    path.write_text(yaml.safe_dump({'task_manager': {'ros__parameters': parameters}}))
    return path


class NodeProcess:
    """A running `task-manager` process (or another) whose log lines tests can wait for."""

    def __init__(
        self,
        params_file: Path | None,
        extra_args: list[str] | None = None,
        wrapper: list[str] | None = None,
        command: list[str] | None = None,
        env: dict[str, str] | None = None,
    ) -> None:
        """`wrapper`: a command that runs the node, e.g. `prlimit --fsize=N --`.

        `command`: another program to run and read the same way (then the rest is unused).
        `env`: adds to the environment (e.g. another ROS_DOMAIN_ID).
        """
        if command is None:
            command = [*(wrapper or []), task_manager_executable()]
            ros_args = list(extra_args or [])
            if params_file is not None:
                ros_args += ['--params-file', str(params_file)]
            if ros_args:
                command += ['--ros-args', *ros_args]
        self.killed = False
        self._program = Path(command[0]).name
        self.process = subprocess.Popen(
            command,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=dict(
                os.environ, RCUTILS_LOGGING_BUFFERED_STREAM='0', PYTHONUNBUFFERED='1', **(env or {})
            ),
        )
        assert self.process.stdout is not None
        self._output = OutputReader(self.process.stdout)

    @property
    def log_lines(self) -> list[str]:
        """What the program printed so far, without Fast DDS's own lines about shared-memory
        ports (see without_shared_memory_lines: a test counts the program's lines)."""
        return [line for line in self._output.lines if SHARED_MEMORY_MARK not in line]

    def wait_for_log(self, pattern: str, timeout_sec: float) -> str:
        """Wait for a log line matching the regular expression `pattern`; return it."""
        line = self._output.find(pattern, timeout_sec)
        if line is None:
            ended = 'the process has exited' if self._output.ended else f'{timeout_sec} s passed'
            raise WaitTimeoutError(
                f'no log line matching {pattern!r} ({ended}); log so far:\n'
                + '\n'.join(self._output.lines)
            )
        return line

    def print_output(self) -> None:
        """Print what the process printed: a fixture does it at teardown, and pytest shows it
        for a test that failed."""
        print('\n'.join(self._output.lines))

    def wait_exit(self, timeout_sec: float) -> int:
        code = self.process.wait(timeout_sec)
        self._output.join(timeout_sec)
        return code

    def kill(self, timeout_sec: float = STOP_TIMEOUT_SEC) -> int:
        """SIGKILL, as a power loss would end it: no clean shutdown."""
        self.killed = True
        self.process.kill()
        return self.wait_exit(timeout_sec)

    def stop(self, timeout_sec: float = STOP_TIMEOUT_SEC) -> int:
        """SIGINT, then wait; kill only as a last resort (a kill leaves DDS files in /dev/shm).
        A process that does not stop in time is aborted, and what it printed (with the stack of
        each of its threads, from faulthandler, which the tests turn on) is printed here."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        try:
            return self.wait_exit(timeout_sec)
        except subprocess.TimeoutExpired:
            self.abort(f'did not stop within {timeout_sec:g} s of SIGINT')
            raise

    def abort(self, why: str) -> None:
        """Every thread's native stack first (gdb's, where installed: Fast DDS's threads hold
        the other end of a deadlock in C), then SIGABRT (faulthandler prints the Python
        threads' stacks), SIGKILL if that is not enough; then print `why`, what the process
        printed and the native stacks."""
        self.killed = True
        native = every_thread(self.process.pid) if self.process.poll() is None else ''
        self.process.send_signal(signal.SIGABRT)
        try:
            self.process.wait(ABORT_TIMEOUT_SEC)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self._output.join(ABORT_TIMEOUT_SEC)
        print(f'{self._program} {why}; aborted, its output:\n' + '\n'.join(self._output.lines))
        if native:
            print(f"{self._program}: every thread's native stack before the abort:\n{native}")


def held_up_with_its_node(program: NodeProcess, node: NodeProcess, timeout_sec: float) -> int:
    """Stop `program` and its `node` (SIGSTOP) longer than its client takes for a hold-up, let
    the program go on while the node stays stopped (nothing can answer it), and return the code
    it exits with within ANSWER_SEC + `timeout_sec`; the node goes on after, in any case."""
    os.kill(node.process.pid, signal.SIGSTOP)
    os.kill(program.process.pid, signal.SIGSTOP)
    try:
        time.sleep(HELD_UP_SEC + 1.5)  # the hold-up is the input, not a wait
        os.kill(program.process.pid, signal.SIGCONT)
        return program.wait_exit(ANSWER_SEC + timeout_sec)
    finally:
        os.kill(node.process.pid, signal.SIGCONT)
        if program.process.poll() is None:
            os.kill(program.process.pid, signal.SIGCONT)


def taskctl(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """Run taskctl of this environment to its end (bounded); `env` adds to the environment.

    It may take TASKCTL_REACH_SEC to reach the Task Manager (a `--timeout` in `args` wins):
    on a loaded 2-core machine a new process can take longer than taskctl's default 5 s to
    discover the node, which is not what the tests test. Its stderr comes without Fast DDS's
    own lines about shared-memory ports (`without_shared_memory_lines`).
    """
    ran = subprocess.run(
        [TASKCTL, '--timeout', str(TASKCTL_REACH_SEC), *args],
        capture_output=True,
        text=True,
        timeout=TASKCTL_TIMEOUT_SEC,
        check=False,
        env=None if env is None else dict(os.environ, **env),
    )
    ran.stderr = without_shared_memory_lines(ran.stderr)
    return ran


def without_shared_memory_lines(output: str) -> str:
    """`output` without Fast DDS's own lines about shared-memory ports: a process that starts
    while another of the run is stopped (SIGSTOP) for seconds, as some tests do, may print
    one (`RTPS_TRANSPORT_SHM Error ... Failed init_port ...`), which is not the program's."""
    return ''.join(
        line for line in output.splitlines(keepends=True) if SHARED_MEMORY_MARK not in line
    )
