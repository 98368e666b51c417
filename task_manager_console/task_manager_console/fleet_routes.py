"""The routes of the whole fleet: a start on "any robot", STOP ALL, the fleet history (JSON or
CSV) and the event stream."""

from datetime import datetime
from typing import Annotated, Any, Literal

from fastapi import FastAPI, Query, Request, Response
from fastapi.responses import StreamingResponse
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from task_manager_web.door_link import EVENT_STREAM_ROUTE
from task_manager_web.doors.access import (
    Caller,
    Operator,
    StreamViewer,
    Viewer,
    check_need,
    check_start_priority,
    runs,
)
from task_manager_web.doors.task_roles import needed_to_start
from task_manager_web.errors import ApiError
from task_manager_web.history.csv_export import COLUMNS
from task_manager_web.history.page import PageFormat, history_page

from task_manager.core.bounds import FLEET_HISTORY_ROWS_DEFAULT, FLEET_HISTORY_ROWS_MAX
from task_manager.core.names import STOP
from task_manager.core.text.json_text import compact_json
from task_manager.core.text.request_text import text_problem
from task_manager.protocol.errors import RefusalCode
from task_manager_console.choosing import Choice, choose_robot
from task_manager_console.documents import FleetStart, FleetStarted, RobotAnswer, StopAll, started
from task_manager_console.fleet_link import FleetLink, Link, checked_answer
from task_manager_console.robot_routes import options_of, robots_document
from task_manager_console.robots import robot_id_problem
from task_manager_console.store.fleet_history import FILTER_TEXTS, HistoryFilter

PAGE = PageFormat(
    columns=('robot_id', *COLUMNS),
    csv_name='fleet_history.csv',
    paging='page on with ended_before (the `ended` of the last task of this page)',
)
OTHERS_SHOWN = 10
"""Candidates named in the refusal of a start no robot can take (the rest are counted)."""
GONE = (RefusalCode.ROBOT_OFFLINE, RefusalCode.UNKNOWN_ROBOT)
"""Error codes of a start on a robot that went away since it was chosen: another is chosen."""


class HistoryParameters(BaseModel):
    """The filters of GET /api/history (empty text: any), newest first."""

    model_config = ConfigDict(extra='forbid')

    robot_id: str = ''
    task_id: str = ''
    task_name: str = ''
    status: Literal['', 'DONE', 'ERROR', 'CANCELED'] = Field('', description='Empty: any.')
    source: str = Field('', examples=['CLOUD:alice'])
    ended_after: datetime | None = Field(None, description='Ended at or after it (UTC if naive).')
    ended_before: datetime | None = Field(None, description='Ended before it (UTC if naive).')
    limit: int = Field(FLEET_HISTORY_ROWS_DEFAULT, ge=1, le=FLEET_HISTORY_ROWS_MAX)
    format: Literal['json', 'csv'] = 'json'


def add_fleet_routes(app: FastAPI) -> None:
    @app.post('/api/fleet/start', tags=['fleet'], status_code=202)
    async def start_on_any_robot(body: FleetStart, caller: Operator, link: Link) -> FleetStarted:
        """Start a task on the robot that can best run it, of `robots` (every robot when left
        out): ONLINE and declaring the task, its conflicting resources free first, then the
        least loaded. The answer names it, why, and why not each other candidate. One that
        goes away before its start is passed over for the next. 409 `no_robot` when none can
        (each candidate's why in the message), `robot_offline` for one robot named alone."""
        check_start_priority(caller, body.priority)
        check_need(caller, lambda: needed_to_start(body.task_name, body.task_data))
        for index, robot_id in enumerate(body.robots or []):
            if problem := robot_id_problem(robot_id):
                raise ApiError(422, RefusalCode.INVALID_REQUEST, problem, f'robots.{index}')
        gone: dict[str, str] = {}  # key: a robot chosen that went away, value: why
        while True:
            choice = _choice(link, body, gone)
            if choice.robot_id is None:
                raise _no_robot(link, body, choice)
            try:
                reply = await link.start(
                    link.fleet.start_task,
                    choice.robot_id,
                    body.task_name,
                    body.task_data,
                    task_id=body.task_id,
                    source=caller.name,
                    **options_of(body),
                )
            except ApiError as error:
                if error.code not in GONE:
                    raise
                gone[choice.robot_id] = f'chosen, then refused: {error.message}'
                continue
            document = {
                **started(choice.robot_id, reply),
                'reason': choice.reason,
                'others': choice.others,
            }
            return checked_answer(FleetStarted, document, choice.robot_id)

    @app.post('/api/fleet/stop', tags=['fleet'])
    async def stop_all(_: Annotated[Caller, runs(STOP)], link: Link) -> StopAll:
        """STOP ALL: system/stop on every robot at once; each robot's answer (its system/stop
        task, or why not: `robot_offline` for a robot not ONLINE, which is not asked,
        `timeout` for one that did not answer)."""
        answers = await link.control(link.fleet.stop_all)
        return StopAll(answers=[_answer(r, answer) for r, answer in answers.items()])

    @app.get(
        '/api/history',
        tags=['fleet'],
        response_model=list[dict[str, Any]],
        responses={200: {'content': {'text/csv': {}}}},
    )
    async def history(
        request: Request,
        _: Viewer,
        link: Link,
        query: Annotated[HistoryParameters, Query()],
    ) -> Response:
        """Every robot's results from the fleet history, newest (by end) first, with their
        `robot_id`; `format=csv` for a spreadsheet. At most --max-history-bytes (8 MiB): a
        larger page is refused, 422 `reply_too_large`, saying how many results fit. 503
        `database_unavailable` while the database cannot be reached."""
        for field in FILTER_TEXTS:
            if problem := text_problem(field, getattr(query, field)):
                raise ApiError(422, RefusalCode.INVALID_REQUEST, problem, field)
        where = HistoryFilter(**query.model_dump(exclude={'format'}))
        results = await link.read(link.fleet.history.query, where)
        return history_page(
            results, query.format == 'csv', request.app.state.max_history_bytes, PAGE
        )

    @app.get('/api/events', tags=['fleet'], **EVENT_STREAM_ROUTE)
    async def events(_: StreamViewer, link: Link) -> StreamingResponse:
        """Server-Sent Events: `hello` (`{"robots": [...], "database_up": bool}`, every robot
        as GET /api/robots gives it), then a `result` event for each result stored (a fleet
        history document) and a `robot` event for each robot changed (its new state)."""
        return link.event_response(
            lambda: compact_json(
                {'robots': robots_document(link), 'database_up': link.fleet.database_up}
            )
        )


def _choice(link: FleetLink, body: FleetStart, gone: dict[str, str]) -> Choice:
    """The choice among the robots, those that went away since they were chosen left out."""
    candidates = [robot for robot in link.fleet.robots.values() if robot.robot_id not in gone]
    requested = None if body.robots is None else [r for r in body.robots if r not in gone]
    choice = choose_robot(body.task_name, candidates, requested)
    return Choice(choice.robot_id, choice.reason, {**gone, **choice.others})


def _no_robot(link: FleetLink, body: FleetStart, choice: Choice) -> ApiError:
    """Why no robot can take the start: `robot_offline` or `unknown_robot` for one robot named
    alone, else `no_robot` with each candidate's why (the first OTHERS_SHOWN)."""
    if body.robots is not None and len(set(body.robots)) == 1:
        robot_id = body.robots[0]
        robot = link.fleet.robot(robot_id)
        why = choice.others.get(robot_id, '')
        if robot is None:
            message = f'no robot {robot_id!r} is known on the broker'
            return ApiError(404, RefusalCode.UNKNOWN_ROBOT, message, 'robots.0')
        if not robot.online:
            since = f' since {robot.since.isoformat()}' if robot.since else ''
            message = f'robot {robot_id} is {why}{since}'
            return ApiError(409, RefusalCode.ROBOT_OFFLINE, message, 'robots.0')
    whys = [f'{robot_id}: {why}' for robot_id, why in sorted(choice.others.items())]
    if len(whys) > OTHERS_SHOWN:
        whys = [*whys[:OTHERS_SHOWN], f'and {len(whys) - OTHERS_SHOWN} more']
    message = choice.reason + (f' ({"; ".join(whys)})' if whys else ': no robot on the broker')
    return ApiError(409, RefusalCode.NO_ROBOT, message, 'robots' if body.robots else 'task_name')


def _answer(robot_id: str, answer: dict[str, Any]) -> RobotAnswer:
    """A robot's answer to STOP ALL; `bad_reply` for one that does not fit (no other robot's
    answer is lost for it)."""
    fields = {name: answer.get(name) for name in ('ok', 'task', 'error')}
    try:
        return RobotAnswer.model_validate({'robot_id': robot_id, **fields})
    except ValidationError:
        error = {'code': RefusalCode.BAD_REPLY, 'message': f'the reply of {robot_id} does not fit'}
        return RobotAnswer(robot_id=robot_id, ok=False, error=error)  # type: ignore[arg-type]
