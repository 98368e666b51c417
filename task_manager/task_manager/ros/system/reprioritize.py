"""system/reprioritize: a new priority for active tasks by id (a queued task moves at once)."""

from typing import Any

from rclpy.node import Node
from task_manager_msgs.srv import ReprioritizeTasks

from task_manager.core.bounds import ids_problem
from task_manager.core.status import TaskStatus
from task_manager.core.system_tasks import REPRIORITIZE_SPEC
from task_manager.core.task import TaskEnd, TaskRecord
from task_manager.messages.json_codec import TaskDataError, message_from_json
from task_manager.rclpy_tools.log import NodeLog
from task_manager.ros.running.execution import TaskRunner
from task_manager.ros.running.protocols import TaskReprioritizing
from task_manager.ros.system.coroutine_execution import CoroutineExecution


class ReprioritizeTasksRunner(TaskRunner):
    """Changes the priority of every listed id; an id that is not active is an error."""

    spec = REPRIORITIZE_SPEC

    def __init__(self, node: Node, priorities: TaskReprioritizing) -> None:
        self._node = node
        self._priorities = priorities

    def parse(self, task_data: str, task_id: str) -> Any:
        request = message_from_json(ReprioritizeTasks.Request, task_data)
        if problem := ids_problem('task_ids', list(request.task_ids)):
            raise TaskDataError('task_ids', problem)
        return request

    async def start(self, message: Any, record: TaskRecord) -> CoroutineExecution:
        return CoroutineExecution(self._node, self._apply(message, record))

    async def _apply(self, message: Any, record: TaskRecord) -> TaskEnd:
        changed, errors = [], []
        for task_id in message.task_ids:
            problem = self._priorities.reprioritize(task_id, message.priority, record.source)
            if problem:
                errors.append(problem)
                NodeLog.of(self._node).warning(
                    f'task {record.task_id} ({record.task_name}): {problem}'
                )
            else:
                changed.append(task_id)
        success = not errors
        status = TaskStatus.DONE if success else TaskStatus.ERROR
        return TaskEnd(
            status, {'success': success, 'successful_changes': changed, 'errors': errors}
        )
