"""What the rest of the node may ask of its running tasks, as narrow protocols.

A helper (a system task, the goals' binding, the scheduler) declares what it uses (run a
request, cancel a task, read an active task's record, pause one, change its priority), and
the node gives it the object that does it: the dispatcher, the pause control or the admission
control. None of them takes the whole dispatcher.
"""

from collections.abc import Callable
from typing import Protocol

from rclpy.task import Future

from task_manager.core.status import CancelReason
from task_manager.core.task import TaskRecord, TaskRequest


class TaskRunning(Protocol):
    """Runs requests to their end (TaskDispatcher)."""

    async def run(
        self, request: TaskRequest, on_admitted: Callable[[TaskRecord], None] | None = None
    ) -> TaskRecord: ...


class TaskCancelling(Protocol):
    """Cancels active tasks (TaskDispatcher)."""

    def cancel(self, task_id: str, reason: CancelReason) -> Future[bool]: ...


class ActiveRecords(Protocol):
    """The records of the active tasks (TaskDispatcher)."""

    def record(self, task_id: str) -> TaskRecord | None: ...

    def records(self) -> list[TaskRecord]: ...


class TaskPausing(Protocol):
    """Pauses and resumes active tasks; '' when done, else why not (PauseControl)."""

    async def pause(self, task_id: str, source: str) -> str: ...

    async def resume(self, task_id: str, source: str) -> str: ...


class TaskReprioritizing(Protocol):
    """Gives active tasks a new priority; '' when done, else why not (AdmissionControl)."""

    def reprioritize(self, task_id: str, priority: int, source: str) -> str: ...
