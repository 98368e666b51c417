"""What every benchmark gets: the client, the running node, the report and the profiler."""

import contextlib
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from action_msgs.msg import GoalStatus

from bench import config
from bench.client import BenchClient, error_code, task_status
from bench.processes import ChildProcess
from bench.profiler import Profile, PySpyRecorder
from bench.replies import BenchError, Reply
from bench.report import Report
from bench.stats import latency_ms


def expect_done(reply: Reply) -> None:
    """An ExecuteTask reply must be DONE."""
    if task_status(reply) != 'DONE':
        raise BenchError(f'task ended {task_status(reply)!r} {error_code(reply)!r}')


def succeeded(reply: Reply) -> bool:
    """Whether a direct action reply is SUCCEEDED."""
    return reply.response is not None and reply.response.status == GoalStatus.STATUS_SUCCEEDED


def expect_succeeded(reply: Reply) -> None:
    if not succeeded(reply):
        raise BenchError('direct goal did not succeed')


def expect_success(reply: Reply) -> None:
    """A direct Trigger reply must say success."""
    if not reply.response.success:
        raise BenchError('direct call did not succeed')


@dataclass
class BenchContext:
    client: BenchClient
    node: ChildProcess
    log_dir: Path
    pids: list[int]
    """The node's and the servers' process ids."""
    profiling: bool = False
    report: Report = field(default_factory=Report)
    # key: what the node was doing, value: py-spy samples of it meanwhile
    profiles: dict[str, Profile] = field(default_factory=dict)

    @contextlib.contextmanager
    def profiled(self, title: str) -> Iterator[None]:
        """Record a py-spy profile of the node during the body (if profiling is on)."""
        if not self.profiling:
            yield
            return
        recorder = PySpyRecorder(self.log_dir / f'profile_{len(self.profiles) + 1}.txt')
        with recorder.recording(self.node.pid):
            yield
        profile = recorder.profile()
        if profile is None:
            self.report.note(f'no profile of {title}: {recorder.failure}')
        else:
            self.profiles[title] = profile

    def settle(self) -> None:
        """Let the node's ExecuteTask server drop the finished goals it keeps (a fixed pause)."""
        print(f'[bench] settling {config.KEPT_GOALS_SEC} s', flush=True)
        time.sleep(config.KEPT_GOALS_SEC)

    def task_latency_ms(
        self, task_name: str, task_data: str, timeout_sec: float = config.SAMPLE_TIMEOUT_SEC
    ) -> float:
        """Round trip of one task through /task_manager/execute_task; it must end DONE."""
        return latency_ms(
            lambda: self.client.send_task(task_name, task_data), expect_done, task_name, timeout_sec
        )

    def fibonacci_task_ms(self) -> float:
        return self.task_latency_ms(config.FIBONACCI_TASK, config.FIBONACCI_DATA)

    def fibonacci_direct_ms(self) -> float:
        return latency_ms(self.client.send_fibonacci, expect_succeeded, 'direct fibonacci')

    def trigger_task_ms(self) -> float:
        return self.task_latency_ms(config.TRIGGER_TASK, config.TRIGGER_DATA)

    def trigger_direct_ms(self) -> float:
        return latency_ms(self.client.call_trigger, expect_success, 'direct trigger')
