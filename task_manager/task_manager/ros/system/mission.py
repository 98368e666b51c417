"""system/mission: subtasks run in order, each an independent task with source `Mission`."""

from typing import Any, Protocol

from rclpy.node import Node
from rclpy.task import Future
from task_manager_msgs.action import Mission

from task_manager.core.bounds import IDS_MAX
from task_manager.core.mission import MissionProgress, SubtaskRefusal, SubtaskRow
from task_manager.core.names import MISSION, MISSION_SOURCE
from task_manager.core.status import CancelReason, ErrorCode
from task_manager.core.system_tasks import MISSION_SPEC
from task_manager.core.task import TaskEnd, TaskRecord, TaskRequest
from task_manager.core.task_spec import PauseMode
from task_manager.core.text.json_text import compact_json
from task_manager.messages.json_codec import (
    TaskDataError,
    message_from_dict,
    parse_json_text,
)
from task_manager.messages.task_messages import mission_results
from task_manager.rclpy_tools.futures import resolved, wait_for
from task_manager.ros.parking_executor import spawn
from task_manager.ros.running.execution import TaskCatalog, TaskRunner
from task_manager.ros.running.protocols import (
    ActiveRecords,
    TaskCancelling,
    TaskPausing,
    TaskRunning,
)
from task_manager.ros.system.coroutine_execution import CoroutineExecution


class Subtasks(TaskRunning, TaskCancelling, ActiveRecords, Protocol):
    """What a mission needs for its subtasks: run, refuse, cancel and read them."""

    def refuse(self, request: TaskRequest, code: ErrorCode, reason: str) -> TaskRecord: ...


class MissionExecution(CoroutineExecution):
    """A running mission; cancelling it cancels its running subtask.

    Paused, it starts no further subtask until resumed; its running subtask goes on, unless
    that subtask pauses by restart: then it is paused too, and resumed with the mission.
    """

    def __init__(
        self,
        node: Node,
        subtasks: Subtasks,
        pauses: TaskPausing,
        progress: MissionProgress,
        mission: TaskRecord,
    ) -> None:
        self._subtasks = subtasks
        self._pauses = pauses
        self._progress = progress
        self._mission = mission
        self._running_id = ''
        # set while paused: completes on resume (or cancel)
        self._resumed: Future[None] | None = None
        # the running subtask this mission's pause paused
        self._paused_subtask_id = ''
        super().__init__(node, self._run_subtasks())

    async def _run_subtasks(self) -> TaskEnd:
        """Each subtask in turn; the mission's feedback shows each start and end."""
        while (row := self._progress.next_subtask()) is not None:
            if self._resumed is not None:
                await resolved(self._node, self._resumed)
                continue  # cancelled meanwhile: next_subtask() says so
            self._running_id = row.task_id
            request = subtask_request(row, self._mission.task_id)
            if row.refusal is not None:  # invalid and skippable: it fails without starting
                subtask = self._subtasks.refuse(request, row.refusal.error_code, row.refusal.reason)
            else:
                subtask = await self._subtasks.run(request, on_admitted=self._on_subtask_turn)
            self._progress.subtask_ended(subtask.status, subtask.cancel_reason)
            self._mission.record_feedback(self._progress.feedback(running=False))
        self._running_id = ''
        return TaskEnd(self._progress.final_status, mission_results(self._progress))

    def _on_subtask_turn(self, _: TaskRecord) -> None:
        self._mission.record_feedback(self._progress.feedback(running=True))

    def pause(self, source: str) -> None:
        if self._resumed is None:
            self._resumed = Future()
        running = self._subtasks.record(self._running_id) if self._running_id else None
        if running is not None and running.spec.pause is PauseMode.RESTART:
            spawn(self._node, self._pause_subtask(running.task_id, source))

    async def _pause_subtask(self, task_id: str, source: str) -> None:
        if await self._pauses.pause(task_id, source):
            return  # it could not pause (it ended meanwhile): nothing to resume
        if self._resumed is None:  # the mission was resumed while its subtask paused
            await self._pauses.resume(task_id, source)
        else:
            self._paused_subtask_id = task_id

    def resume(self, source: str) -> None:
        self._wake()
        if self._paused_subtask_id:
            task_id, self._paused_subtask_id = self._paused_subtask_id, ''
            spawn(self._node, self._pauses.resume(task_id, source))

    def _wake(self) -> None:
        resumed, self._resumed = self._resumed, None
        if resumed is not None:
            resumed.set_result(None)

    async def cancel(self, timeout_sec: float) -> bool:
        self._progress.cancel(CancelReason.MISSION)
        self._wake()
        if self._running_id:
            self._subtasks.cancel(self._running_id, CancelReason.MISSION)
        return await wait_for(self._node, self.outcome, timeout_sec)


class MissionRunner(TaskRunner):
    """Starts missions, checking every subtask's name and data before the first one runs.

    An invalid subtask (unknown task, bad data, a nested mission) that may be skipped fails
    when its turn comes, and the mission goes on. One that may not be skipped fails the
    mission before anything runs: the mission is refused with its mission_results (that
    subtask ERROR, the others RECEIVED), and the subtask's own result is published.
    """

    spec = MISSION_SPEC

    def __init__(
        self, node: Node, subtasks: Subtasks, pauses: TaskPausing, catalog: TaskCatalog
    ) -> None:
        self._node = node
        self._subtasks = subtasks
        self._pauses = pauses
        self._catalog = catalog

    def parse(self, task_data: str, task_id: str) -> MissionProgress:
        progress, problems = self._plan(task_data)
        if problems:
            self._refuse(progress, task_id)
            raise _invalid_mission(progress, problems)
        return progress

    def validate(self, task_data: str) -> None:
        """Raise TaskDataError as parse does, but refuse (publish) nothing: a mission that
        is only being scheduled has no subtask requests yet."""
        progress, problems = self._plan(task_data)
        if problems:
            progress.fail_before_start()
            raise _invalid_mission(progress, problems)

    def _plan(self, task_data: str) -> tuple[MissionProgress, dict[str, str]]:
        """The mission's rows, each checked, and the unskippable problems (key: the field at
        fault, value: why)."""
        goal = message_from_dict(Mission.Goal, _subtask_data_as_text(parse_json_text(task_data)))
        if len(goal.subtasks) > IDS_MAX:
            raise TaskDataError(
                'subtasks', f'{len(goal.subtasks)} subtasks; a mission has at most {IDS_MAX}'
            )
        for index, subtask in enumerate(goal.subtasks):
            if not subtask.task_name.strip():
                raise TaskDataError(f'subtasks[{index}].task_name', 'every subtask needs a name')
        progress = MissionProgress.plan(
            [(s.task_id, s.task_name, s.task_data, s.allow_skipping) for s in goal.subtasks]
        )
        if duplicates := progress.duplicate_ids():
            raise TaskDataError('subtasks', f'subtask ids given more than once: {duplicates}')
        problems: dict[str, str] = {}
        for index, row in enumerate(progress.rows):
            field, row.refusal = self._check(index, row)
            if row.refusal is not None and not row.allow_skipping:
                problems[field] = row.refusal.reason
        return progress, problems

    def _check(self, index: int, row: SubtaskRow) -> tuple[str, SubtaskRefusal | None]:
        """The field that is wrong and why the subtask cannot run; ('', None) if it can."""
        runner = self._catalog.get(row.task_name)
        name_field = f'subtasks[{index}].task_name'
        if runner is None:
            reason = self._catalog.unknown_task_reason(row.task_name)
            return name_field, SubtaskRefusal(ErrorCode.UNKNOWN_TASK, reason)
        if runner.spec.task_name == MISSION:
            reason = 'a mission cannot contain a mission'
            return name_field, SubtaskRefusal(ErrorCode.TASK_DATA_PARSING_FAILED, reason)
        try:
            runner.parse(row.task_data, row.task_id)
        except TaskDataError as error:
            refusal = SubtaskRefusal(ErrorCode.TASK_DATA_PARSING_FAILED, str(error))
            return f'subtasks[{index}].task_data', refusal
        return '', None

    def _refuse(self, progress: MissionProgress, mission_id: str) -> None:
        """Fail the mission before it starts; each unskippable invalid subtask gets its result."""
        for row in progress.unskippable_refusals():
            assert row.refusal is not None
            self._subtasks.refuse(
                subtask_request(row, mission_id), row.refusal.error_code, row.refusal.reason
            )
        progress.fail_before_start()

    async def start(self, message: MissionProgress, record: TaskRecord) -> MissionExecution:
        return MissionExecution(self._node, self._subtasks, self._pauses, message, record)

    def claimed_resources(self, message: MissionProgress) -> frozenset[str]:
        """A mission holds its subtasks' declared resources as one unit while it runs."""
        return frozenset(
            resource
            for row in message.rows
            if (runner := self._catalog.get(row.task_name)) is not None
            for resource in runner.spec.resources
        )


def _invalid_mission(progress: MissionProgress, problems: dict[str, str]) -> TaskDataError:
    field, reason = next(iter(problems.items()))
    if len(problems) > 1:
        reason += f' (and {len(problems) - 1} more invalid subtask(s))'
    return TaskDataError(field, reason, mission_results(progress))


def subtask_request(row: SubtaskRow, mission_id: str) -> TaskRequest:
    """The request a mission makes for one of its subtasks (source `Mission`)."""
    return TaskRequest(row.task_id, row.task_name, MISSION_SOURCE, row.task_data, mission_id)


def _subtask_data_as_text(data: Any) -> Any:
    """A mission's document with each subtask's task_data given as a JSON object (as a mission
    file writes it) turned into the JSON text Mission's goal holds; the rest as it came."""
    subtasks = data.get('subtasks') if isinstance(data, dict) else None
    for subtask in subtasks if isinstance(subtasks, list) else ():
        if isinstance(subtask, dict) and isinstance(subtask.get('task_data'), dict):
            subtask['task_data'] = compact_json(subtask['task_data'])
    return data
