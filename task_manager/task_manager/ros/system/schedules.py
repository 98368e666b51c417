"""system/schedule, system/unschedule and system/enable_schedule (see ros/running/scheduler.py)."""

import dataclasses
import json
import time
import uuid
from typing import Any

from rclpy.node import Node
from task_manager_msgs.srv import EnableSchedules, ScheduleTask, Unschedule

from task_manager.core.bounds import SCHEDULES_MAX
from task_manager.core.schedules.request import parse_schedule_request
from task_manager.core.schedules.schedule import (
    OverlapPolicy,
    ScheduleError,
    ScheduleSpec,
)
from task_manager.core.status import TaskStatus
from task_manager.core.system_tasks import ENABLE_SCHEDULE_SPEC, SCHEDULE_SPEC, UNSCHEDULE_SPEC
from task_manager.core.task import TaskEnd, TaskRecord
from task_manager.messages.json_codec import TaskDataError, message_from_json
from task_manager.messages.task_messages import options_of_message, stamp
from task_manager.ros.running.execution import TaskCatalog, TaskRunner
from task_manager.ros.running.scheduler import TaskScheduler
from task_manager.ros.system.coroutine_execution import CoroutineExecution
from task_manager.ros.system.mission import MissionRunner

# key: field of ScheduleTask.Request, value: its name in core/schedules/schedule.py's requests
_RENAMED_FIELDS = {'window_start': 'start', 'window_end': 'end'}


def new_schedule_id() -> str:
    return f'schedule-{uuid.uuid4().hex[:8]}'


def _instant_end(body: TaskEnd) -> Any:
    async def end() -> TaskEnd:
        return body

    return end()


class ScheduleTaskRunner(TaskRunner):
    """system/schedule: checks the schedule and its task's data now; runs come later."""

    spec = SCHEDULE_SPEC

    def __init__(self, node: Node, catalog: TaskCatalog, scheduler: TaskScheduler) -> None:
        self._node = node
        self._catalog = catalog
        self._scheduler = scheduler

    def parse(self, task_data: str, task_id: str) -> ScheduleSpec:
        request = message_from_json(ScheduleTask.Request, task_data)
        fields = {
            _RENAMED_FIELDS.get(name, name): getattr(request, name)
            for name in request.get_fields_and_field_types()
        }
        request.options.has_priority |= _gives_priority(task_data)
        fields['options'] = options_of_message(request.options)
        try:
            spec = parse_schedule_request(fields, '', time.time(), new_schedule_id)
        except ScheduleError as error:
            raise TaskDataError(_field_name(error.field), str(error)) from None
        self._check_task(spec)
        return spec

    def _check_task(self, spec: ScheduleSpec) -> None:
        """The scheduled task must exist and take its task_data, and the id must be free."""
        if len(self._scheduler.book) >= SCHEDULES_MAX:
            raise TaskDataError(
                '',
                f'this Task Manager keeps at most {SCHEDULES_MAX} schedules; remove one first '
                '(system/unschedule)',
            )
        if spec.schedule_id in self._scheduler.book:
            raise TaskDataError(
                'schedule_id',
                f'schedule {spec.schedule_id!r} exists; remove it first (system/unschedule) '
                'or give another id',
            )
        runner = self._catalog.get(spec.task_name)
        if runner is None:
            raise TaskDataError('task_name', self._catalog.unknown_task_reason(spec.task_name))
        try:
            if isinstance(runner, MissionRunner):
                runner.validate(spec.task_data)
            else:
                runner.parse(spec.task_data, '')
        except TaskDataError as error:
            reason = f'not a valid goal of {spec.task_name}: {error}'
            raise TaskDataError('task_data', reason) from None
        if spec.overlap is OverlapPolicy.ALLOW_ALL and not runner.spec.reentrant:
            raise TaskDataError(
                'overlap',
                f'ALLOW_ALL runs overlap, and {spec.task_name} is not reentrant (a new goal '
                'replaces the running one); use SKIP, BUFFER_ONE or CANCEL_OTHER',
            )

    async def start(self, message: ScheduleSpec, record: TaskRecord) -> CoroutineExecution:
        spec = dataclasses.replace(message, created_by=record.source)
        try:
            state = self._scheduler.add(spec)
        except ValueError as error:  # the id was taken since parse
            end = TaskEnd(TaskStatus.ERROR, _schedule_result(False, spec, None, str(error)))
        else:
            end = TaskEnd(TaskStatus.DONE, _schedule_result(True, spec, state.next_run, ''))
        return CoroutineExecution(self._node, _instant_end(end))


def _field_name(field: str) -> str:
    """The request's name of a field core/schedules/schedule.py names (first of a list of them)."""
    first = field.split(',')[0]
    return {core: msg for msg, core in _RENAMED_FIELDS.items()}.get(first, first)


def _schedule_result(
    success: bool, spec: ScheduleSpec, next_run: float | None, message: str
) -> dict[str, Any]:
    run = stamp(next_run)
    return {
        'success': success,
        'schedule_id': spec.schedule_id,
        'next_run': {'sec': run.sec, 'nanosec': run.nanosec},
        'message': message or f'{spec.task_name}, {spec.describe()}',
    }


class _ScheduleIdsRunner(TaskRunner):
    """Applies a change to schedules by id; unknown ids fail with a line each."""

    spec: Any
    _request_type: Any

    def __init__(self, node: Node, scheduler: TaskScheduler) -> None:
        self._node = node
        self._scheduler = scheduler

    def parse(self, task_data: str, task_id: str) -> Any:
        return message_from_json(self._request_type, task_data)

    def _apply(self, message: Any) -> tuple[str, list[str]]:
        """The result's field of the ids changed, and those ids."""
        raise NotImplementedError

    async def start(self, message: Any, record: TaskRecord) -> CoroutineExecution:
        field, done = self._apply(message)
        errors = [
            f'no schedule {schedule_id!r}'
            for schedule_id in message.schedule_ids
            if schedule_id not in done
        ]
        success = not errors
        status = TaskStatus.DONE if success else TaskStatus.ERROR
        end = TaskEnd(status, {'success': success, field: done, 'errors': errors})
        return CoroutineExecution(self._node, _instant_end(end))


class UnscheduleRunner(_ScheduleIdsRunner):
    """system/unschedule: removes schedules; their runs already started go on."""

    spec = UNSCHEDULE_SPEC
    _request_type = Unschedule.Request

    def _apply(self, message: Any) -> tuple[str, list[str]]:
        return 'removed', self._scheduler.remove(list(message.schedule_ids))


class EnableSchedulesRunner(_ScheduleIdsRunner):
    """system/enable_schedule: disables schedules (state kept) or enables them again."""

    spec = ENABLE_SCHEDULE_SPEC
    _request_type = EnableSchedules.Request

    def _apply(self, message: Any) -> tuple[str, list[str]]:
        return 'changed', self._scheduler.set_enabled(
            list(message.schedule_ids), bool(message.enabled)
        )


def _gives_priority(task_data: str) -> bool:
    """JSON's `"options": {"priority": 0}` gives a priority, though has_priority is left out."""
    data = json.loads(task_data)  # parsed once already: it is a JSON object
    options = data.get('options')
    return isinstance(options, dict) and 'priority' in options
