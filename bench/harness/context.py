"""What every benchmark gets: the client, the running node, the report and the profiler."""

import contextlib
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from action_msgs.msg import GoalStatus
from rclpy.task import Future

from bench.harness import config
from bench.harness.client import BenchClient, error_code, task_status
from bench.harness.processes import ChildProcess, start_node
from bench.harness.profiler import Profile, PySpyRecorder
from bench.harness.replies import BenchError, Reply, wait_reply
from bench.harness.report import Report
from bench.harness.stats import latency_ms
from task_manager.core.names import INSTANCES_TOPIC
from task_manager.ros.instances import INSTANCES_SUBSCRIPTION_QOS
from task_manager_msgs.msg import TaskManagerInstance

WARM_UP_ATTEMPTS = 5
WARM_UP_TIMEOUT_SEC = 2.0


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


def wait_announced(client: BenchClient, pid: int, timeout_sec: float) -> None:
    """Wait until the Task Manager of process `pid` has announced itself on its instances topic.

    After a restart, the graph may still list the stopped node's servers for a moment: this
    tells the new node apart.
    """
    announced = threading.Event()

    def on_instance(instance: Any) -> None:
        if instance.pid == pid:
            announced.set()

    node = client.harness.node
    subscription = node.create_subscription(
        TaskManagerInstance, INSTANCES_TOPIC, on_instance, INSTANCES_SUBSCRIPTION_QOS
    )
    try:
        if not announced.wait(timeout_sec):
            raise BenchError(f'Task Manager pid {pid}: no announcement within {timeout_sec} s')
    finally:
        node.destroy_subscription(subscription)


def warm_up(client: BenchClient) -> None:
    """Retry a goal for an unknown task (answered at once) until a round trip works.

    Seeing the server is not enough: DDS may match its reply path to a new client a moment
    later, and a reply sent before that is lost.
    """
    for attempt in range(WARM_UP_ATTEMPTS):
        try:
            wait_reply(client.send_task('__bench_warm_up__', '{}'), 'warm-up', WARM_UP_TIMEOUT_SEC)
            return
        except BenchError:
            print(f'[bench] warm-up round trip {attempt + 1} lost, retrying', flush=True)
    raise BenchError(f'no ExecuteTask round trip in {WARM_UP_ATTEMPTS} attempts')


@dataclass
class BenchContext:
    client: BenchClient
    node: ChildProcess
    servers: ChildProcess
    log_dir: Path
    profiling: bool = False
    report: Report = field(default_factory=Report)
    # key: what the node was doing, value: py-spy samples of it meanwhile
    profiles: dict[str, Profile] = field(default_factory=dict)

    def connect(self) -> None:
        """Wait for the node and the servers, then for one ExecuteTask round trip to work."""
        try:
            wait_announced(self.client, self.node.pid, config.CONNECT_TIMEOUT_SEC)
            self.client.wait_for_servers(config.CONNECT_TIMEOUT_SEC)
            warm_up(self.client)
        except BenchError as error:
            raise BenchError(
                f'{error}\n--- node log ---\n{self.node.log_tail()}\n--- servers log ---\n'
                f'{self.servers.log_tail()}'
            ) from error

    def restart_node(self, name: str = 'task_manager', **parameters: Any) -> None:
        """Stop the node; start it again with these node-level parameters, logging to `name`."""
        self.node.stop()
        params_file = config.write_node_params(self.log_dir, f'{name}_params', **parameters)
        self.node = start_node(params_file, self.log_dir, name)
        self.connect()

    def accepted_task(self, task_name: str, task_data: str, task_id: str) -> Future[Any]:
        """Send a task; return its reply future once the manager has accepted its goal."""
        accepted: Future[Any] = Future()
        replied = self.client.send_task(task_name, task_data, task_id, accepted)
        wait_reply(accepted, f'{task_id} accepted')
        return replied

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
        """A short pause between timed measurements (config.SETTLE_SEC)."""
        print(f'[bench] settling {config.SETTLE_SEC} s', flush=True)
        time.sleep(config.SETTLE_SEC)

    def wait_kept_goals_gone(self, since: float | None = None) -> None:
        """Let the node's ExecuteTask server and rclpy's servers drop the finished goals they
        keep (KEPT_GOALS_SEC after the last one ended), before a measurement of memory or idle
        CPU, or of a server that walks them. `since`: when the last goal ended
        (time.monotonic()), where the caller knows it; else just now."""
        elapsed = time.monotonic() - since if since is not None else 0.0
        left = config.KEPT_GOALS_SEC - elapsed
        if left > 0:
            print(f'[bench] waiting {left:.1f} s for the kept goals to go', flush=True)
            time.sleep(left)

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
