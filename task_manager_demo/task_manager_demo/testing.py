"""Helpers for tests that run the demo: its processes and the feedback of its actions."""

import contextlib
import os
import queue
import re
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from task_manager.client import TaskManagerClient
from task_manager.testing.harness import WaitTimeoutError
from task_manager.testing.process import NodeProcess
from task_manager_demo.children import Child, Events, Exited, Line
from task_manager_demo.robot_interface import ROBOT_READY_LOG
from task_manager_demo.run_demo import default_params_file

STOP_TIMEOUT_SEC = 10.0
START_TIMEOUT_SEC = 30.0


def robot_command(*parameters: str) -> list[str]:
    """`task-manager-demo-robot` with `name:=value` ROS parameters."""
    command = [str(Path(sys.executable).with_name('task-manager-demo-robot'))]
    if parameters:
        command += ['--ros-args', *(arg for p in parameters for arg in ('-p', p))]
    return command


class DemoProcess:
    """A process in its own process group whose output lines a test waits for."""

    def __init__(self, name: str, command: list[str], cwd: Path | None = None) -> None:
        self.events: Events = queue.SimpleQueue()
        # a crash (SIGSEGV, SIGABRT) leaves the Python stack of each thread in the output
        self.child = Child(name, command, self.events, cwd=cwd, env={'PYTHONFAULTHANDLER': '1'})

    @property
    def pid(self) -> int:
        return self.child.process.pid

    @property
    def output(self) -> str:
        return '\n'.join(self.child.output)

    def wait_for_line(self, pattern: str, timeout_sec: float) -> str:
        """Wait for an output line matching the regular expression `pattern`; return it."""
        regex = re.compile(pattern)
        if match := next((line for line in self.child.output if regex.search(line)), None):
            return match
        deadline = time.monotonic() + timeout_sec
        while True:
            try:
                event = self.events.get(timeout=max(deadline - time.monotonic(), 0.0))
            except queue.Empty:
                raise self._failure(
                    f'no line matching {pattern!r} within {timeout_sec} s'
                ) from None
            if isinstance(event, Line) and regex.search(event.text):
                return event.text
            if isinstance(event, Exited):
                raise self._failure(f'exited before a line matching {pattern!r}')

    def _failure(self, what: str) -> WaitTimeoutError:
        return WaitTimeoutError(f'{self.child.name} {what}; output:\n{self.output}')

    def signal_group(self, signum: int = signal.SIGINT) -> None:
        """Signal the whole process group, as a terminal's Ctrl-C does."""
        os.killpg(self.pid, signum)

    def wait_exit(self, timeout_sec: float) -> int:
        """Its exit code; past the timeout, its whole process group is killed (a launcher
        under `make` is not left running on the test's ROS domain)."""
        code = self.child.wait(timeout_sec)
        if code is None:
            self.child.kill()
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.pid, signal.SIGKILL)
            raise self._failure(f'still running after {timeout_sec} s (killed)')
        return code

    def stop(self, timeout_sec: float = STOP_TIMEOUT_SEC) -> int:
        """SIGINT to its process group, as Ctrl-C, then a bounded wait; a kill only as a last
        resort."""
        try:
            self.signal_group(signal.SIGINT)
        except ProcessLookupError:  # the group has gone: the process too, or about to
            self.child.interrupt()
        return self.wait_exit(timeout_sec)


class FeedbackRecorder:
    """Feedback callback of an action goal; tests wait on conditions over what arrived."""

    def __init__(self) -> None:
        self.messages: list[Any] = []
        self._changed = threading.Condition()

    def __call__(self, feedback_message: Any) -> None:
        with self._changed:
            self.messages.append(feedback_message.feedback)
            self._changed.notify_all()

    def wait_until(self, predicate: Callable[[list[Any]], bool], timeout_sec: float) -> None:
        with self._changed:
            if not self._changed.wait_for(lambda: predicate(self.messages), timeout_sec):
                raise WaitTimeoutError(
                    f'feedback condition not met within {timeout_sec} s: {self.messages}'
                )

    def snapshot(self) -> list[Any]:
        with self._changed:
            return list(self.messages)


@contextlib.contextmanager
def demo_robot(
    client_name: str, *robot_parameters: str, client_timeout_sec: float = START_TIMEOUT_SEC
) -> Iterator[TaskManagerClient]:
    """The simulated robot (with these `name:=value` parameters) and a Task Manager with the
    demo's tasks, both ready, and a client of it; at the end both must stop cleanly."""
    robot = DemoProcess('robot', robot_command(*robot_parameters))
    task_manager = NodeProcess(default_params_file())
    try:
        robot.wait_for_line(ROBOT_READY_LOG, START_TIMEOUT_SEC)
        task_manager.wait_for_log(r'Task Manager ready', START_TIMEOUT_SEC)
        with TaskManagerClient(client_name, timeout_sec=client_timeout_sec) as client:
            client.wait_until_available()
            yield client
    finally:
        assert task_manager.stop() == 0, '\n'.join(task_manager.log_lines)
        code = robot.stop()
        assert code == 0, f'the robot exited with {code}:\n{robot.output}'
