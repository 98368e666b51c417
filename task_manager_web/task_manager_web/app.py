"""The gateway's HTTP API, event stream and dashboard (a FastAPI application).

Requests and answers are the documents of `task_manager.protocol` (its JSON Schema files);
the OpenAPI description is at /openapi.json and browsable at /docs (Swagger UI, served here).
Before routing, a request passes the doors (middlewares) of `doors/settings.py`, outermost
first: FrontDoor (Host allow-list; the security headers of every answer), RequestMetrics,
ReadBound (reads in flight per client), BodyDoor (size, time and JSON of the body).
"""

import asyncio
import json
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import FastAPI, Query, Request, Response
from fastapi.responses import FileResponse, StreamingResponse
from fastapi.staticfiles import StaticFiles

from task_manager.client import TaskHandle, TaskManagerClient
from task_manager.core.names import CANCEL_TASK, MISSION, REPRIORITIZE, STOP
from task_manager.core.text.request_text import text_problem
from task_manager.gateway import requests as gateway_requests
from task_manager.gateway.documents import decisions_json, declared_json, result_json, task_json
from task_manager.protocol import models
from task_manager.protocol.errors import RefusalCode
from task_manager_web.door_link import EVENT_STREAM_ROUTE
from task_manager_web.doors.access import (
    Access,
    Caller,
    MetricsViewer,
    Operator,
    StreamViewer,
    Viewer,
    check_need,
    check_start_priority,
    runs,
)
from task_manager_web.doors.settings import DoorSettings, add_doors, add_whoami, door_app
from task_manager_web.doors.task_roles import needed_by_steps, needed_to_start
from task_manager_web.errors import ApiError
from task_manager_web.history.page import history_page
from task_manager_web.metrics import GatewayMetrics, node_snapshot
from task_manager_web.node_link import Link, NodeLink
from task_manager_web.operator_routes import add_operator_routes
from task_manager_web.request_metrics import METRICS_ROUTE, metrics_response

WAIT_DEFAULT_SEC = 30.0
WAIT_MAX_SEC = 600.0
STATIC = Path(__file__).with_name('static')


@dataclass(frozen=True)
class Settings(DoorSettings):
    read_without_token: bool = False
    source: str = 'WEB'
    """The source of every task started, cancelled or stopped here (a request cannot say),
    followed by `:<name>` for a token with a name."""


def create_app(
    settings: Settings,
    make_client: Callable[[], TaskManagerClient],
    close_client: Callable[[TaskManagerClient], None] = TaskManagerClient.close,
) -> FastAPI:
    """The gateway; `make_client` is called at start-up, `close_client` at shutdown."""

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        client = await asyncio.to_thread(make_client)
        app.state.link = NodeLink(client, asyncio.get_running_loop())
        stop_counting = metrics.watch(client)
        try:
            yield
        finally:
            stop_counting()
            app.state.link.close()
            await asyncio.to_thread(close_client, client)

    app = door_app(
        'Task Manager web gateway',
        'Start, watch and stop the tasks of a robot running the ROS 2 Task Manager.',
        lifespan,
    )
    access = Access(
        settings.tokens,
        settings.read_without_token,
        settings.source,
        settings.metrics_without_token,
    )
    metrics = GatewayMetrics()
    app.state.metrics = metrics
    add_doors(app, settings, access, metrics.request_counts)
    add_whoami(app)
    _add_routes(app)
    add_operator_routes(app)
    app.mount('/static', StaticFiles(directory=str(STATIC)), name='static')
    app.mount('/swagger', StaticFiles(packages=[('fastapi_swagger', 'resources')]), name='swagger')
    return app


class HistoryParameters(models.HistoryQuery):
    format: Literal['json', 'csv'] = 'json'


Wait = Annotated[bool, Query(description='Answer once the task ended (bounded by timeout_sec).')]
WaitSec = Annotated[
    float, Query(gt=0, le=WAIT_MAX_SEC, description='The longest wait, with wait=true.')
]


def _add_routes(app: FastAPI) -> None:
    @app.get('/', include_in_schema=False)
    async def dashboard() -> FileResponse:
        return FileResponse(str(STATIC / 'index.html'))

    @app.get('/docs', include_in_schema=False)
    async def docs() -> FileResponse:
        """Swagger UI (fastapi_swagger's files), its URLs relative: never built from Host."""
        return FileResponse(str(STATIC / 'docs.html'))

    @app.get('/api/health', tags=['state'])
    async def health(link: Link) -> dict[str, Any]:
        """Whether the gateway reaches a Task Manager, and its task events (no token needed)."""
        return {
            'connected': link.connected,
            'events': link.events_connected,
            'event_streams': link.stream_count,
        }

    @app.get('/metrics', **METRICS_ROUTE)
    async def metrics(_: MetricsViewer, link: Link, request: Request) -> Response:
        """Prometheus metrics (text format): the tasks ended by name and status, their
        durations, the active, paused and queued counts, the schedules' runs and misses, and
        this gateway's requests. Needs a token unless --metrics-without-token."""
        gateway_metrics: GatewayMetrics = request.app.state.metrics
        snapshot = await node_snapshot(link)
        # no await from here to the exposition: another scrape cannot come in between
        gateway_metrics.set_node(link.connected, snapshot)
        return metrics_response(gateway_metrics.registry)

    @app.get('/api/tasks', tags=['tasks'])
    async def declared_tasks(_: Viewer, link: Link) -> list[models.DeclaredTask]:
        """The tasks the Task Manager runs, each with a JSON Schema of its task_data."""
        declared = await link.read(link.client.declared_tasks)
        return [models.DeclaredTask.model_validate(declared_json(entry)) for entry in declared]

    @app.post(
        '/api/tasks/start',
        tags=['tasks'],
        status_code=202,
        responses={200: {'model': models.Started, 'description': 'The task ended (wait=true).'}},
    )
    async def start_task(
        body: models.StartTask,
        caller: Operator,
        link: Link,
        response: Response,
        wait: Wait = False,
        timeout_sec: WaitSec = WAIT_DEFAULT_SEC,
    ) -> models.Started:
        """Start a task: 202 with its id at once, or 200 with its end (wait=true).

        The options (priority, on_conflict, timeout_sec, queue_timeout_sec,
        feedback_timeout_sec) are the task's declaration's when left out. A task the Task
        Manager refuses (unknown, bad task_data, a busy resource, ...) is no HTTP error: it
        ends ERROR with its error code and message. A priority needs role admin, and a system
        task the role of its own route (system/reprioritize, system/schedule: admin), in a
        mission's step or a schedule's task too.
        """
        check_start_priority(caller, body.priority)
        check_need(caller, lambda: needed_to_start(body.task_name, body.task_data))
        handle = await link.start(
            gateway_requests.start_task,
            link.client,
            body,
            task_id=body.task_id,
            source=caller.source,
        )
        return await _started(link, handle, response, wait, timeout_sec)

    @app.post(
        '/api/missions',
        tags=['tasks'],
        status_code=202,
        responses={200: {'model': models.Started, 'description': 'The mission ended.'}},
    )
    async def start_mission(
        body: models.StartMission,
        caller: Annotated[Caller, runs(MISSION)],
        link: Link,
        response: Response,
        wait: Wait = False,
        timeout_sec: WaitSec = WAIT_DEFAULT_SEC,
    ) -> models.Started:
        """Start system/mission with these subtasks; its id and the subtasks' ids at once.

        Its options are a start's, for the mission as one unit (it queues as one); a
        priority needs role admin, and a step that is a system task the role of its own route.
        """
        check_start_priority(caller, body.priority)
        steps = [step.model_dump() for step in body.subtasks]
        check_need(caller, lambda: needed_by_steps(steps, 'subtasks'))
        handle, subtask_ids = await link.start(
            gateway_requests.start_mission,
            link.client,
            body,
            task_id=body.task_id,
            source=caller.source,
        )
        return await _started(link, handle, response, wait, timeout_sec, subtask_ids)

    @app.post('/api/tasks/cancel', tags=['tasks'])
    async def cancel_tasks(
        body: models.CancelTasks, caller: Annotated[Caller, runs(CANCEL_TASK)], link: Link
    ) -> models.Task:
        """system/cancel_task: cancel these tasks, whoever started them; its result."""
        result = await link.control(
            gateway_requests.cancel_tasks, link.client, body, source=caller.source
        )
        return models.Task.model_validate(result_json(result))

    @app.post('/api/tasks/reprioritize', tags=['tasks'])
    async def reprioritize(
        body: models.Reprioritize, caller: Annotated[Caller, runs(REPRIORITIZE)], link: Link
    ) -> models.Task:
        """system/reprioritize: a new priority for these active tasks (a queued one moves in
        the queue at once); its result, with `successful_changes` and `errors`."""
        result = await link.control(
            gateway_requests.reprioritize, link.client, body, source=caller.source
        )
        return models.Task.model_validate(result_json(result))

    @app.post('/api/stop', tags=['tasks'])
    async def stop(caller: Annotated[Caller, runs(STOP)], link: Link) -> models.Task:
        """system/stop: cancel every task declared cancel_on_stop; its result."""
        result = await link.control(link.client.stop, source=caller.source)
        return models.Task.model_validate(result_json(result))

    @app.get('/api/active', tags=['state'])
    async def active(_: Viewer, link: Link) -> list[models.Task]:
        """Every active task, with its stamps and latest feedback."""
        states = await link.read(link.client.task_states)
        return [models.Task.model_validate(task_json(s)) for s in states]

    # before /api/tasks/{task_id:path}, which would take `ID/why` for an id
    @app.get('/api/tasks/{task_id:path}/why', tags=['state'])
    async def why(task_id: str, _: Viewer, link: Link) -> list[models.Decision]:
        """Every decision the Task Manager took about a task, active or ended, oldest first:
        why it was queued, refused, pre-empted, timed out, retried or reprioritized."""
        refused = text_problem('task_id', task_id) is not None
        decisions = None if refused else await link.read(gateway_requests.why, link.client, task_id)
        if decisions is None:
            raise ApiError(
                404, RefusalCode.UNKNOWN_TASK_ID, f'the Task Manager knows no task {task_id!r}'
            )
        return [models.Decision.model_validate(d) for d in decisions_json(decisions)]

    @app.get('/api/tasks/{task_id:path}', tags=['state'])
    async def task(task_id: str, _: Viewer, link: Link) -> models.Task:
        """One task, active or ended: its state, stamps, latest feedback and result."""
        # an id no task can have (NUL, which ROS would cut, a newline, ...) is looked up nowhere
        refused = text_problem('task_id', task_id) is not None
        states = [] if refused else await link.read(link.client.task_states, [task_id])
        if not states:
            raise ApiError(
                404, RefusalCode.UNKNOWN_TASK_ID, f'the Task Manager knows no task {task_id!r}'
            )
        return models.Task.model_validate(task_json(states[0]))

    @app.get(
        '/api/history',
        tags=['state'],
        response_model=list[models.Task],
        responses={200: {'content': {'text/csv': {}}}},
    )
    async def history(
        request: Request, _: Viewer, link: Link, query: Annotated[HistoryParameters, Query()]
    ) -> Response:
        """Ended tasks from the durable history, newest first; format=csv for a spreadsheet.
        At most --max-history-bytes (8 MiB): a larger page is refused, 422 reply_too_large,
        saying how many tasks fit."""
        # the query's fields are the client's filters, by the same names
        states = await link.read(link.client.history, **query.model_dump(exclude={'format'}))
        tasks = [task_json(s) for s in states]
        return history_page(tasks, query.format == 'csv', request.app.state.max_history_bytes)

    @app.get('/api/events', tags=['state'], **EVENT_STREAM_ROUTE)
    async def events(_: StreamViewer, link: Link) -> StreamingResponse:
        """Server-Sent Events: `hello` and `connection` ({"connected": bool}), then a `task`
        event (a TaskEvent document) for every change of every task."""
        return link.event_response(lambda: json.dumps({'connected': link.connected}))


async def _started(
    link: NodeLink,
    handle: TaskHandle,
    response: Response,
    wait: bool,
    timeout_sec: float,
    subtask_ids: list[str] | None = None,
) -> models.Started:
    result = await link.result(handle, timeout_sec) if wait else None
    if result is None and handle.done():
        result = handle.result_future.result()
    state = handle.state  # the final one (with sequence and last feedback) once ENDED came
    task: dict[str, Any] | None = None
    if result is not None:
        response.status_code = 200
        task = task_json(state) if state is not None and state.is_final else result_json(result)
    elif state is not None:
        task = task_json(state)
    return models.Started.model_validate(
        {
            'task_id': handle.task_id,
            'subtask_ids': subtask_ids or [],
            'ended': result is not None,
            'task': task,
        }
    )
