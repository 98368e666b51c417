"""The seams between the dispatcher and whatever runs a task (action, service, system), and
the catalog of the declared tasks' runners."""

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Protocol

from rclpy.task import Future

from task_manager.core.task import TaskEnd, TaskRecord
from task_manager.core.task_spec import TaskSpec
from task_manager.rclpy_tools.request_window import DEFAULT_SIZE


@dataclass(frozen=True)
class RunnerTimeouts:
    """Bounds on the waits of starting a task on its server."""

    server_wait_sec: float = 1.0
    """How long a missing server may take to appear before the start fails."""
    goal_response_sec: float = 5.0
    """How long a server may take to accept or reject a goal."""
    service_response_sec: float = 120.0
    """How long a service task may take to respond."""
    server_check_period_sec: float = 1.0
    """How often the server of running tasks is checked."""
    server_loss_timeout_sec: float = 5.0
    """How long a server may give no sign of life before its tasks end ERROR."""
    server_requests_in_flight: int = DEFAULT_SIZE
    """Goals, cancels and results asked again, sent to one action server, and a service task's
    calls to its service, at most this many unanswered at a time (a server keeps 10 unread
    requests by default; 0: no bound)."""


class Execution(Protocol):
    """A task that has started; `outcome` completes with its TaskEnd."""

    outcome: Future[TaskEnd]

    async def cancel(self, timeout_sec: float) -> bool:
        """Ask the task to stop; True once it has ended within `timeout_sec`."""
        ...


class TaskRunner(Protocol):
    """Starts tasks of one declared task type; a runner subclasses it for `claimed_resources`."""

    spec: TaskSpec

    def parse(self, task_data: str, task_id: str) -> Any:
        """The goal/request message of task `task_id`'s `task_data` (JSON); raises TaskDataError."""
        ...

    async def start(self, message: Any, record: TaskRecord) -> Execution:
        """Start the task; raises TaskRequestError(TASK_START_FAILED) if it cannot."""
        ...

    def claimed_resources(self, message: Any) -> frozenset[str]:
        """Resources a task holds beside its declaration's, while it runs (a mission: its
        subtasks'); none by default."""
        return frozenset()


class TaskCatalog:
    """The runner of every declared task, by task name: the user's tasks and the built-in ones."""

    def __init__(self) -> None:
        # key: task name, value: the runner of its tasks
        self._runners: dict[str, TaskRunner] = {}

    def add(self, runners: Iterable[TaskRunner]) -> None:
        for runner in runners:
            self._runners[runner.spec.task_name] = runner

    def get(self, task_name: str) -> TaskRunner | None:
        return self._runners.get(task_name)

    def unknown_task_reason(self, task_name: str) -> str:
        """Why a task name is refused, with the names that would be accepted."""
        known = ', '.join(sorted(self._runners))
        return f'unknown task {task_name!r}; declared tasks: {known}'
