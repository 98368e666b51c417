"""system/pause and system/resume: pause and resume tasks by id (see running/pause_control.py)."""

from collections.abc import Callable, Coroutine
from typing import Any

from rclpy.node import Node
from rclpy.task import Future
from task_manager_msgs.srv import PauseTasks, ResumeTasks

from task_manager.core.bounds import ids_problem
from task_manager.core.status import TaskStatus
from task_manager.core.system_tasks import PAUSE_SPEC, RESUME_SPEC
from task_manager.core.task import TaskEnd, TaskRecord
from task_manager.core.task_spec import TaskSpec
from task_manager.messages.json_codec import TaskDataError, message_from_json
from task_manager.rclpy_tools.futures import all_completed, resolved
from task_manager.rclpy_tools.log import NodeLog
from task_manager.ros.running.execution import TaskRunner
from task_manager.ros.running.protocols import TaskPausing
from task_manager.ros.system.coroutine_execution import CoroutineExecution

# One pause or resume of one task for a source: '' when done, else why not.
TaskStep = Callable[[str, str], Coroutine[Any, Any, str]]


class _PauseStepRunner(TaskRunner):
    """Applies one step (pause or resume) to every listed id at once."""

    spec: TaskSpec
    _request_type: Any
    _done_field: str

    def __init__(self, node: Node, pauses: TaskPausing) -> None:
        self._node = node
        self._pauses = pauses

    def _step(self) -> TaskStep:
        raise NotImplementedError

    def parse(self, task_data: str, task_id: str) -> Any:
        request = message_from_json(self._request_type, task_data)
        if problem := ids_problem('task_ids', list(request.task_ids)):
            raise TaskDataError('task_ids', problem)
        return request

    async def start(self, message: Any, record: TaskRecord) -> CoroutineExecution:
        return CoroutineExecution(self._node, self._apply(list(message.task_ids), record))

    async def _apply(self, task_ids: list[str], record: TaskRecord) -> TaskEnd:
        step = self._step()
        assert self._node.executor is not None
        answers: list[Future[str]] = [
            self._node.executor.create_task(step(task_id, record.source))  # type: ignore[call-overload]
            for task_id in task_ids
        ]
        await resolved(self._node, all_completed(answers))
        errors = [answer.result() or '' for answer in answers]
        done = [t for t, error in zip(task_ids, errors, strict=True) if not error]
        problems = [error for error in errors if error]
        log = NodeLog.of(self._node)
        for problem in problems:
            log.warning(f'task {record.task_id} ({record.task_name}): {problem}')
        success = not problems
        status = TaskStatus.DONE if success else TaskStatus.ERROR
        return TaskEnd(status, {'success': success, self._done_field: done, 'errors': problems})


class PauseTasksRunner(_PauseStepRunner):
    """system/pause: missions pause between subtasks, `pause: restart` tasks at once."""

    spec = PAUSE_SPEC
    _request_type = PauseTasks.Request
    _done_field = 'successful_pauses'

    def _step(self) -> TaskStep:
        return self._pauses.pause


class ResumeTasksRunner(_PauseStepRunner):
    """system/resume: paused tasks run again."""

    spec = RESUME_SPEC
    _request_type = ResumeTasks.Request
    _done_field = 'successful_resumes'

    def _step(self) -> TaskStep:
        return self._pauses.resume
