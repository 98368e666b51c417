"""The tasks the manager is handling now, and the conflict rules between them."""

from collections.abc import Iterator

from task_manager.core.errors import TaskRequestError
from task_manager.core.status import ErrorCode
from task_manager.core.task import TaskRecord
from task_manager.core.task_spec import TaskSpec


class TaskRegistry:
    """Tasks from receipt until they end, by id, in the order they were received."""

    def __init__(self) -> None:
        # key: task id, value: the task's record (RECEIVED or IN_PROGRESS)
        self.active_tasks_by_id: dict[str, TaskRecord] = {}

    def __len__(self) -> int:
        return len(self.active_tasks_by_id)

    def __iter__(self) -> Iterator[TaskRecord]:
        return iter(list(self.active_tasks_by_id.values()))

    def get(self, task_id: str) -> TaskRecord | None:
        return self.active_tasks_by_id.get(task_id)

    def admit(self, record: TaskRecord) -> None:
        """Track a new task; its id must not be in use by a task that has not ended."""
        if record.task_id in self.active_tasks_by_id:
            raise TaskRequestError(
                ErrorCode.DUPLICATE_TASK_ID,
                f'task id {record.task_id!r} is already in use by an active task',
            )
        self.active_tasks_by_id[record.task_id] = record

    def remove(self, task_id: str) -> None:
        self.active_tasks_by_id.pop(task_id, None)

    def started(self) -> list[TaskRecord]:
        """Tasks that have started and not ended (IN_PROGRESS or PAUSED)."""
        return [t for t in self.active_tasks_by_id.values() if t.status.is_started]

    def listed(self) -> list[TaskRecord]:
        """Tasks shown in active_tasks: queued, running or paused."""
        return [t for t in self.active_tasks_by_id.values() if t.status.is_listed]

    def conflicts_of(self, spec: TaskSpec, new_task_id: str) -> list[TaskRecord]:
        """Tasks that must be cancelled before a new task of `spec` may start.

        A non-reentrant task replaces the active tasks of the same name; a blocking task
        replaces every other active blocking task.
        """
        return [
            record
            for record in self.active_tasks_by_id.values()
            if record.task_id != new_task_id
            and (
                (not spec.reentrant and record.task_name == spec.task_name)
                or (spec.blocking and record.spec.blocking)
            )
        ]

    def cancelled_by_stop(self) -> list[TaskRecord]:
        return [t for t in self.active_tasks_by_id.values() if t.spec.cancel_on_stop]
