"""The routes of one robot: its state, and what the robot web API does, sent to it over the
broker (a start, a mission, cancel, pause, resume, reprioritize, confirm, stop).

Each request document is the robot web API's (`task_manager.protocol.models`), and each needs
the role its effect needs (task_manager_web's roles: a system task started or run as a
mission's step needs the role of the route that runs it, a priority of one's own an admin's).
The source of what is started is the bridge's (`CLOUD`) followed by the token's name
(`CLOUD:alice`): the history says who did it.
"""

from collections.abc import Callable
from typing import Annotated, Any, TypeVar, cast

from fastapi import FastAPI
from fastapi.responses import JSONResponse
from pydantic import BaseModel
from task_manager_mqtt.fleet_types import StartOptions
from task_manager_web.doors.access import (
    Caller,
    Operator,
    Viewer,
    check_need,
    check_start_priority,
    runs,
)
from task_manager_web.doors.task_roles import needed_by_steps, needed_to_start
from task_manager_web.errors import ApiError

from task_manager.core.names import CANCEL_TASK, MISSION, PAUSE, REPRIORITIZE, RESUME, STOP
from task_manager.core.text.json_text import compact_json
from task_manager.core.text.request_text import text_problem
from task_manager.protocol import models
from task_manager.protocol.errors import RefusalCode
from task_manager_console.documents import RobotStarted, started
from task_manager_console.fleet_link import FleetLink, Link, checked_answer
from task_manager_console.robots import RobotState

M = TypeVar('M', bound=BaseModel)
OPTION_FIELDS = StartOptions.__optional_keys__
"""The options of a start, by the names of the request's fields."""


def robots_document(link: FleetLink) -> list[dict[str, Any]]:
    """Every robot's document, by id."""
    return [robot_document(robot) for _, robot in sorted(link.fleet.robots.items())]


def robot_document(robot: RobotState) -> dict[str, Any]:
    """A robot's state, and `queue_length`: its active tasks queued."""
    document = robot.document()
    document['queue_length'] = sum(1 for t in robot.active if t.get('status') == 'QUEUED')
    return document


def options_of(request: models.StartTask | models.StartMission) -> StartOptions:
    """The options a start gives (those left out take the robot's declaration)."""
    given = request.model_dump(include=set(OPTION_FIELDS), exclude_none=True)
    return cast(StartOptions, given)


def add_robot_routes(app: FastAPI) -> None:
    @app.get('/api/robots', tags=['robots'], response_class=CompactJson)
    async def robots(_: Viewer, link: Link) -> CompactJson:
        """Every robot on the broker, by id: `robot_id`, `connection_state` (ONLINE, OFFLINE,
        CONNECTIONBROKEN), `since`, `silent`, `tasks` (declared), `active` (running, queued,
        paused, confirmations waiting), `queue_length`, `schedules`, `last_result`, ..."""
        return CompactJson(robots_document(link))

    @app.get('/api/robots/{robot_id}', tags=['robots'], response_class=CompactJson)
    async def robot(robot_id: str, _: Viewer, link: Link) -> CompactJson:
        """One robot, as in GET /api/robots; 404 `unknown_robot` for one never seen."""
        return CompactJson(robot_document(link.robot(robot_id)))

    @app.post('/api/robots/{robot_id}/tasks/start', tags=['robots'], status_code=202)
    async def start_task(
        robot_id: str, body: models.StartTask, caller: Operator, link: Link
    ) -> RobotStarted:
        """Start a task on the robot (the robot web API's start document): 202 with the
        robot's reply (its id; `duplicate` for an id it knew). Its result comes to the fleet
        history and the event stream. 409 `robot_offline` for a robot not ONLINE."""
        check_start_priority(caller, body.priority)
        check_need(caller, lambda: needed_to_start(body.task_name, body.task_data))
        link.robot(robot_id)
        reply = await link.start(
            link.fleet.start_task,
            robot_id,
            body.task_name,
            body.task_data,
            task_id=body.task_id,
            source=caller.name,
            **options_of(body),
        )
        return checked_answer(RobotStarted, started(robot_id, reply), robot_id)

    @app.post('/api/robots/{robot_id}/missions', tags=['robots'], status_code=202)
    async def start_mission(
        robot_id: str,
        body: models.StartMission,
        caller: Annotated[Caller, runs(MISSION)],
        link: Link,
    ) -> RobotStarted:
        """Start system/mission with these subtasks on the robot: 202 with its id and the
        subtasks' ids. A step that is a system task needs the role of its own route."""
        check_start_priority(caller, body.priority)
        steps = [step.model_dump() for step in body.subtasks]
        check_need(caller, lambda: needed_by_steps(steps, 'subtasks'))
        link.robot(robot_id)
        reply = await link.start(
            link.fleet.start_mission,
            robot_id,
            steps,
            task_id=body.task_id,
            source=caller.name,
            **options_of(body),
        )
        return checked_answer(RobotStarted, started(robot_id, reply), robot_id)

    @app.post('/api/robots/{robot_id}/tasks/cancel', tags=['robots'])
    async def cancel(
        robot_id: str,
        body: models.CancelTasks,
        _: Annotated[Caller, runs(CANCEL_TASK)],
        link: Link,
    ) -> models.Task:
        """system/cancel_task on the robot: cancel these tasks; its result."""
        return await _control(link, models.Task, link.fleet.client.cancel, robot_id, body.task_ids)

    @app.post('/api/robots/{robot_id}/tasks/pause', tags=['robots'])
    async def pause(
        robot_id: str, body: models.PauseTasks, _: Annotated[Caller, runs(PAUSE)], link: Link
    ) -> models.Paused:
        """system/pause on the robot; the ids paused and why not the others."""
        return await _control(link, models.Paused, link.fleet.client.pause, robot_id, body.task_ids)

    @app.post('/api/robots/{robot_id}/tasks/resume', tags=['robots'])
    async def resume(
        robot_id: str, body: models.ResumeTasks, _: Annotated[Caller, runs(RESUME)], link: Link
    ) -> models.Resumed:
        """system/resume on the robot; the ids running again and why not the others."""
        return await _control(
            link, models.Resumed, link.fleet.client.resume, robot_id, body.task_ids
        )

    @app.post('/api/robots/{robot_id}/tasks/reprioritize', tags=['robots'])
    async def reprioritize(
        robot_id: str,
        body: models.Reprioritize,
        _: Annotated[Caller, runs(REPRIORITIZE)],
        link: Link,
    ) -> models.Task:
        """system/reprioritize on the robot (an admin's); its result, with
        `successful_changes` and `errors`."""
        return await _control(
            link,
            models.Task,
            link.fleet.client.reprioritize,
            robot_id,
            body.task_ids,
            body.priority,
        )

    @app.post('/api/robots/{robot_id}/tasks/{task_id:path}/confirm', tags=['robots'])
    async def confirm(
        robot_id: str, task_id: str, body: models.ConfirmTask, caller: Operator, link: Link
    ) -> models.Confirmed:
        """Answer a waiting system/confirm of the robot (confirm, or reject); its result names
        the bridge's source and the caller as `by` (`CLOUD:alice`). 404 `unknown_task_id`, 409
        `not_waiting`."""
        link.robot(robot_id)
        if problem := text_problem('task_id', task_id):
            raise ApiError(422, RefusalCode.INVALID_REQUEST, problem, 'task_id')
        confirmed = await link.control(
            link.fleet.client.confirm,
            robot_id,
            task_id,
            reject=body.reject,
            comment=body.comment,
            source=caller.name,
        )
        return checked_answer(models.Confirmed, confirmed, robot_id)

    @app.post('/api/robots/{robot_id}/stop', tags=['robots'])
    async def stop(robot_id: str, _: Annotated[Caller, runs(STOP)], link: Link) -> models.Task:
        """system/stop on the robot: cancel its tasks declared cancel_on_stop; its result."""
        return await _control(link, models.Task, link.fleet.client.stop, robot_id)


async def _control(
    link: FleetLink, model: type[M], call: Callable[..., Any], robot_id: str, *args: Any
) -> M:
    """`call(robot_id, *args)`, a control of the robot (cancel, pause, stop, ...) that waits
    for its reply, checked as `model`; 422 or 404 first for a robot_id that names no robot."""
    link.robot(robot_id)
    reply = await link.control(call, robot_id, *args)
    return checked_answer(model, reply, robot_id)


class CompactJson(JSONResponse):
    """An answer written once as compact JSON, without a model's round trip (200 robots'
    documents)."""

    def render(self, content: Any) -> bytes:
        if isinstance(content, list):
            return f'[{",".join(compact_json(item) for item in content)}]'.encode()
        return compact_json(content).encode()
