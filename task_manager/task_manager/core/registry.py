"""The tasks the manager is handling now, and the conflict rules between them."""

from collections.abc import Iterator
from typing import Generic, Protocol

from typing_extensions import TypeVar

from task_manager.core.admission.claims import implied_resources
from task_manager.core.errors import TaskRequestError
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.core.task import TaskRecord
from task_manager.core.task_spec import TaskSpec


class ActiveTask(Protocol):
    """What the registry reads of a task: a TaskRecord, or the node's run of one."""

    @property
    def task_id(self) -> str: ...

    @property
    def spec(self) -> TaskSpec: ...

    @property
    def status(self) -> TaskStatus: ...


Entry = TypeVar('Entry', bound=ActiveTask, default=TaskRecord)


class TaskRegistry(Generic[Entry]):
    """Tasks from receipt until they end, by id, in the order they were received.

    Its entries are records (the default), or whatever holds a task while it runs (the
    node's TaskRun): one table of the active tasks.
    """

    def __init__(self) -> None:
        # key: task id, value: the task's entry (RECEIVED, QUEUED, IN_PROGRESS or PAUSED)
        self.active_tasks_by_id: dict[str, Entry] = {}

    def __len__(self) -> int:
        return len(self.active_tasks_by_id)

    def __iter__(self) -> Iterator[Entry]:
        return iter(list(self.active_tasks_by_id.values()))

    def get(self, task_id: str) -> Entry | None:
        return self.active_tasks_by_id.get(task_id)

    def admit(self, entry: Entry) -> None:
        """Track a new task; its id must not be in use by a task that has not ended."""
        if entry.task_id in self.active_tasks_by_id:
            raise TaskRequestError(
                ErrorCode.DUPLICATE_TASK_ID,
                f'task id {entry.task_id!r} is already in use by an active task',
            )
        self.active_tasks_by_id[entry.task_id] = entry

    def remove(self, task_id: str) -> None:
        self.active_tasks_by_id.pop(task_id, None)

    def listed(self) -> list[Entry]:
        """Tasks shown in active_tasks: queued, running or paused."""
        return [t for t in self.active_tasks_by_id.values() if t.status.is_listed]

    def conflicts_of(self, spec: TaskSpec, new_task_id: str) -> list[Entry]:
        """Active tasks that share a resource with a new task of `spec`, in arrival order.

        With no resources declared these are the original's rules: a non-reentrant task
        conflicts with the active tasks of its name, a blocking task with every other blocking
        task (see core/admission/claims.py); the arbiter decides what happens to them.
        """
        wanted = _resources(spec)
        return [
            entry
            for entry in self.active_tasks_by_id.values()
            if entry.task_id != new_task_id and wanted & _resources(entry.spec)
        ]

    def cancelled_by_stop(self) -> list[Entry]:
        return [t for t in self.active_tasks_by_id.values() if t.spec.cancel_on_stop]


def _resources(spec: TaskSpec) -> frozenset[str]:
    return implied_resources(spec.task_name, spec.resources, spec.blocking, spec.reentrant)
