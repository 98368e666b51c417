"""system/mission: subtasks run in order, each an independent task with source `Mission`."""

from typing import Any

from rclpy.node import Node
from task_manager_msgs.action import Mission
from task_manager_msgs.msg import SubtaskResult

from task_manager.core.mission import MISSION_SOURCE, MissionProgress
from task_manager.core.status import CancelReason
from task_manager.core.task import TaskEnd, TaskRecord, TaskRequest
from task_manager.ros.dispatcher import TaskDispatcher
from task_manager.ros.futures import wait_for
from task_manager.ros.message_json import TaskDataError, message_from_json, message_to_dict
from task_manager.ros.system.coroutine_execution import CoroutineExecution
from task_manager.ros.system.specs import MISSION, MISSION_SPEC


class MissionExecution(CoroutineExecution):
    """A running mission; cancelling it cancels its running subtask."""

    def __init__(
        self, node: Node, dispatcher: TaskDispatcher, progress: MissionProgress, mission_id: str
    ) -> None:
        self._dispatcher = dispatcher
        self._progress = progress
        self._mission_id = mission_id
        self._running_id = ''
        super().__init__(node, self._run_subtasks())

    async def _run_subtasks(self) -> TaskEnd:
        while (row := self._progress.next_subtask()) is not None:
            self._running_id = row.task_id
            request = TaskRequest(
                row.task_id, row.task_name, MISSION_SOURCE, row.task_data, self._mission_id
            )
            subtask = await self._dispatcher.run(request)
            self._progress.subtask_ended(subtask.status, subtask.cancel_reason)
        self._running_id = ''
        return TaskEnd(self._progress.final_status, self._results())

    def _results(self) -> dict[str, Any]:
        rows = [
            SubtaskResult(
                task_id=r.task_id,
                task_name=r.task_name,
                task_status=str(r.status),
                skipped=r.skipped,
            )
            for r in self._progress.rows
        ]
        return message_to_dict(Mission.Result(mission_results=rows))

    async def cancel(self, timeout_sec: float) -> bool:
        self._progress.cancel(CancelReason.MISSION)
        if self._running_id:
            self._dispatcher.cancel(self._running_id, CancelReason.MISSION)
        return await wait_for(self._node, self.outcome, timeout_sec)


class MissionRunner:
    """Starts missions, checking every subtask's name and data before the first one runs."""

    spec = MISSION_SPEC

    def __init__(self, node: Node, dispatcher: TaskDispatcher) -> None:
        self._node = node
        self._dispatcher = dispatcher

    def parse(self, task_data: str) -> MissionProgress:
        goal = message_from_json(Mission.Goal, task_data)
        for index, subtask in enumerate(goal.subtasks):
            self._check_subtask(index, subtask)
        progress = MissionProgress.plan(
            [(s.task_id, s.task_name, s.task_data, s.allow_skipping) for s in goal.subtasks]
        )
        if duplicates := progress.duplicate_ids():
            raise TaskDataError('subtasks', f'subtask ids given more than once: {duplicates}')
        return progress

    def _check_subtask(self, index: int, subtask: Any) -> None:
        runner = self._dispatcher.runners_by_name.get(subtask.task_name)
        if runner is None or runner.spec.task_name == MISSION:
            problem = 'a mission cannot contain a mission' if runner else 'unknown task'
            raise TaskDataError(f'subtasks[{index}].task_name', f'{problem}: {subtask.task_name!r}')
        try:
            runner.parse(subtask.task_data)
        except TaskDataError as error:
            raise TaskDataError(f'subtasks[{index}].task_data', str(error)) from error

    async def start(self, message: MissionProgress, record: TaskRecord) -> MissionExecution:
        return MissionExecution(self._node, self._dispatcher, message, record.task_id)
