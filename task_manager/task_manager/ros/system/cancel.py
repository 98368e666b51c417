"""system/cancel_task (alias system/cancel_tasks) and system/stop."""

from typing import Any, Protocol

from rclpy.node import Node
from task_manager_msgs.srv import CancelTasks, StopTasks

from task_manager.core.bounds import ids_problem
from task_manager.core.status import CancelReason, TaskStatus
from task_manager.core.system_tasks import CANCEL_TASK_ALIAS_SPEC, CANCEL_TASK_SPEC, STOP_SPEC
from task_manager.core.task import TaskEnd, TaskRecord
from task_manager.messages.json_codec import TaskDataError, message_from_json
from task_manager.rclpy_tools.futures import all_completed, resolved
from task_manager.rclpy_tools.log import NodeLog
from task_manager.ros.running.execution import TaskRunner
from task_manager.ros.running.protocols import ActiveRecords, TaskCancelling
from task_manager.ros.system.coroutine_execution import CoroutineExecution


class CancelledTasks(TaskCancelling, ActiveRecords, Protocol):
    """What cancel_task and stop need: the active tasks, to cancel them."""

    def cancelled_by_stop(self) -> list[TaskRecord]: ...


async def cancel_all(
    node: Node, tasks: TaskCancelling, task_ids: list[str], reason: CancelReason
) -> list[str]:
    """Cancel every id at once; return the ids whose cancel completed in time."""
    cancels = [tasks.cancel(task_id, reason) for task_id in task_ids]
    await resolved(node, all_completed(cancels))
    return [t for t, cancel in zip(task_ids, cancels, strict=True) if cancel.result()]


def _end(success: bool, result: dict[str, Any]) -> TaskEnd:
    return TaskEnd(TaskStatus.DONE if success else TaskStatus.ERROR, result)


class CancelTasksRunner(TaskRunner):
    """Cancels tasks by id; ids that are not active count as cancelled (with a warning)."""

    def __init__(self, node: Node, tasks: CancelledTasks, alias: bool) -> None:
        self.spec = CANCEL_TASK_ALIAS_SPEC if alias else CANCEL_TASK_SPEC
        self._node = node
        self._tasks = tasks

    def parse(self, task_data: str, task_id: str) -> Any:
        request = message_from_json(CancelTasks.Request, task_data)
        if problem := ids_problem('cancelled_tasks', list(request.cancelled_tasks)):
            raise TaskDataError('cancelled_tasks', problem)
        return request

    async def start(self, message: Any, record: TaskRecord) -> CoroutineExecution:
        return CoroutineExecution(self._node, self._cancel(list(message.cancelled_tasks), record))

    async def _cancel(self, task_ids: list[str], record: TaskRecord) -> TaskEnd:
        for task_id in task_ids:
            if self._tasks.record(task_id) is None:
                NodeLog.of(self._node).warning(
                    f'task {record.task_id} ({record.task_name}): no active task {task_id!r} '
                    'to cancel; counted as cancelled'
                )
        cancelled = await cancel_all(self._node, self._tasks, task_ids, CancelReason.CANCEL_TASK)
        success = len(cancelled) == len(task_ids)
        return _end(success, {'success': success, 'successful_cancels': cancelled})


class StopTasksRunner(TaskRunner):
    """Cancels every active task declared with cancel_on_stop."""

    spec = STOP_SPEC

    def __init__(self, node: Node, tasks: CancelledTasks) -> None:
        self._node = node
        self._tasks = tasks

    def parse(self, task_data: str, task_id: str) -> Any:
        return message_from_json(StopTasks.Request, task_data)

    async def start(self, message: Any, record: TaskRecord) -> CoroutineExecution:
        return CoroutineExecution(self._node, self._stop())

    async def _stop(self) -> TaskEnd:
        task_ids = [r.task_id for r in self._tasks.cancelled_by_stop()]
        cancelled = await cancel_all(self._node, self._tasks, task_ids, CancelReason.STOP)
        success = len(cancelled) == len(task_ids)
        return _end(success, {'success': success})
