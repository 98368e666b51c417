"""The routes that pause and resume tasks, answer confirmations and keep the schedules: each a
system task (or confirm_task) run through the client in a control thread, its request and
answer documents `task_manager.protocol`'s.
"""

from typing import Annotated

from fastapi import FastAPI

from task_manager.client import ConfirmAnswer
from task_manager.core.confirmation import AnswerRefusal, not_found_reason
from task_manager.core.names import ENABLE_SCHEDULE, PAUSE, RESUME, SCHEDULE, UNSCHEDULE
from task_manager.core.text.request_text import text_problem
from task_manager.gateway import requests as gateway_requests
from task_manager.gateway.documents import (
    confirmed_json,
    paused_json,
    result_json,
    resumed_json,
    schedule_json,
    scheduled_json,
)
from task_manager.protocol import models
from task_manager.protocol.errors import RefusalCode
from task_manager_web.doors.access import Caller, Operator, Viewer, check_need, runs
from task_manager_web.doors.task_roles import (
    Need,
    needed_by_steps,
    needed_to_start,
    with_runs_priority,
)
from task_manager_web.errors import ApiError
from task_manager_web.node_link import Link


def add_operator_routes(app: FastAPI) -> None:
    @app.post('/api/tasks/pause', tags=['tasks'])
    async def pause(
        body: models.PauseTasks, caller: Annotated[Caller, runs(PAUSE)], link: Link
    ) -> models.Paused:
        """system/pause: pause these tasks (a mission between its subtasks, a task declared
        `pause: restart` at once); the ids paused and why not the others."""
        result = await link.control(gateway_requests.pause, link.client, body, source=caller.source)
        return models.Paused.model_validate(paused_json(result))

    @app.post('/api/tasks/resume', tags=['tasks'])
    async def resume(
        body: models.ResumeTasks, caller: Annotated[Caller, runs(RESUME)], link: Link
    ) -> models.Resumed:
        """system/resume: resume these paused tasks; the ids running again and why not the
        others."""
        result = await link.control(
            gateway_requests.resume, link.client, body, source=caller.source
        )
        return models.Resumed.model_validate(resumed_json(result))

    @app.post('/api/tasks/{task_id:path}/confirm', tags=['tasks'])
    async def confirm(
        task_id: str, body: models.ConfirmTask, caller: Operator, link: Link
    ) -> models.Confirmed:
        """Answer a waiting system/confirm: confirm it (DONE) or reject it (ERROR, `rejected`);
        its result names the caller (`by`: WEB:alice). 404 for an id the Task Manager does
        not know, 409 `not_waiting` for a task that is no waiting confirmation."""
        if text_problem('task_id', task_id) is not None:
            raise _no_task(task_id)
        answer = await link.control(
            gateway_requests.confirm, link.client, task_id, body, source=caller.source
        )
        if not answer.taken:
            raise _not_taken(answer)
        return models.Confirmed.model_validate(confirmed_json(answer, body, caller.source))

    @app.get('/api/schedules', tags=['schedules'])
    async def schedules(_: Viewer, link: Link) -> list[models.Schedule]:
        """Every schedule: when it runs, its next run, its last run's status, its options."""
        found = await link.read(link.client.schedules)
        return [models.Schedule.model_validate(schedule_json(s)) for s in found]

    @app.post('/api/schedules', tags=['schedules'])
    async def schedule(
        body: models.ScheduleTask, caller: Annotated[Caller, runs(SCHEDULE)], link: Link
    ) -> models.Scheduled:
        """system/schedule: a task or a mission run at set times (exactly one of at,
        delay_sec, period_sec, cron). One the Task Manager refuses (an unknown task, bad
        task_data or cron, an id taken, ...) is no HTTP error: `scheduled` is false and
        `message` says why. What it runs needs the role its start would need."""
        check_need(caller, lambda: _needed_to_schedule(body))
        result = await link.control(
            gateway_requests.schedule, link.client, body, source=caller.source
        )
        return models.Scheduled.model_validate(scheduled_json(result, body.schedule_id))

    @app.patch('/api/schedules/{schedule_id:path}', tags=['schedules'])
    async def enable_schedule(
        schedule_id: str,
        body: models.EnableSchedule,
        caller: Annotated[Caller, runs(ENABLE_SCHEDULE)],
        link: Link,
    ) -> models.Schedule:
        """system/enable_schedule: disable a schedule (no runs, its counts kept) or enable it
        again (from its next due time after now); the schedule then."""
        _check_schedule_id(schedule_id)
        found = await link.control(
            gateway_requests.enable_schedule,
            link.client,
            schedule_id,
            body,
            source=caller.source,
        )
        if found is None:
            raise _unknown(schedule_id)
        return models.Schedule.model_validate(schedule_json(found))

    @app.delete('/api/schedules/{schedule_id:path}', tags=['schedules'])
    async def unschedule(
        schedule_id: str, caller: Annotated[Caller, runs(UNSCHEDULE)], link: Link
    ) -> models.Task:
        """system/unschedule: remove a schedule (its runs already started go on); the system
        task, ended."""
        _check_schedule_id(schedule_id)
        result = await link.control(
            gateway_requests.unschedule, link.client, schedule_id, source=caller.source
        )
        if result is None:
            raise _unknown(schedule_id)
        return models.Task.model_validate(result_json(result))


def _needed_to_schedule(body: models.ScheduleTask) -> Need:
    """What the schedule's task or mission, and its runs' priority, need."""
    if body.subtasks is None:
        scheduled = needed_to_start(body.task_name, body.task_data)
    else:
        scheduled = needed_by_steps([step.model_dump() for step in body.subtasks], 'subtasks')
    return with_runs_priority(scheduled, body.priority is not None, 'priority')


def _check_schedule_id(schedule_id: str) -> None:
    """An id no schedule can have (NUL, a newline, ...) is looked up nowhere."""
    if text_problem('schedule_id', schedule_id) is not None:
        raise _unknown(schedule_id)


def _no_task(task_id: str) -> ApiError:
    return ApiError(404, RefusalCode.UNKNOWN_TASK_ID, not_found_reason(task_id))


def _not_taken(answer: ConfirmAnswer) -> ApiError:
    """The HTTP error of an answer the Task Manager did not take."""
    if answer.error_code == AnswerRefusal.NOT_FOUND:
        return ApiError(404, RefusalCode.UNKNOWN_TASK_ID, answer.message)
    if answer.error_code == AnswerRefusal.NOT_WAITING:
        return ApiError(409, RefusalCode.NOT_WAITING, answer.message)
    return ApiError(422, answer.error_code or RefusalCode.INVALID_REQUEST, answer.message)


def _unknown(schedule_id: str) -> ApiError:
    return ApiError(
        404, RefusalCode.UNKNOWN_SCHEDULE_ID, f'the Task Manager has no schedule {schedule_id!r}'
    )
