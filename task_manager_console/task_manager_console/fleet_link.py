"""The console's doors' link to the Fleet: its blocking calls awaitable from asyncio, its changes
handed to the event streams, and its errors as HTTP answers.

The Fleet's calls block (a robot's reply over the broker, a query of the database): they run
in three pools of threads, so that no kind of request waits behind another: reads of the
database, starts, and control (stop, STOP ALL, cancel, pause, resume, reprioritize, confirm).
A flood of history queries or of starts never holds up a stop.

What the Fleet reports on its threads (a robot changed, a result stored) is handed to the event
loop with `call_soon_threadsafe`, one wake-up for what came meanwhile; the robots changed are
sent once each per wake-up, as they are then (the newest state), and each result stored once,
in the order stored. With no stream open, nothing is turned into JSON.
"""

import asyncio
import contextlib
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from typing import Annotated, Any, TypeVar

from fastapi import Depends, Request
from pydantic import BaseModel, ValidationError
from task_manager_mqtt.fleet_types import FleetError
from task_manager_web.door_link import DoorLink
from task_manager_web.errors import ApiError
from task_manager_web.event_stream import STREAM_QUEUE_MAX, EventStream

from task_manager.core.text.json_text import compact_json
from task_manager.protocol.errors import RefusalCode, describe
from task_manager_console.fleet import Change, Fleet
from task_manager_console.robots import RobotState, robot_id_problem
from task_manager_console.store.fleet_history import DatabaseUnavailable

T = TypeVar('T')
M = TypeVar('M', bound=BaseModel)
# key: an error code of a FleetError (the console's, the broker's or a robot's reply), value:
# the HTTP status it is answered with; any other code: 502 (the robot refused it)
STATUS_OF_CODE: dict[str, int] = {
    RefusalCode.INVALID_REQUEST: 422,
    RefusalCode.PAYLOAD_TOO_LARGE: 413,
    RefusalCode.UNKNOWN_ROBOT: 404,
    RefusalCode.UNKNOWN_TASK_ID: 404,
    RefusalCode.UNKNOWN_SCHEDULE_ID: 404,
    RefusalCode.ROBOT_OFFLINE: 409,
    RefusalCode.NOT_WAITING: 409,
    RefusalCode.TASK_MANAGER_UNAVAILABLE: 503,
    RefusalCode.TIMEOUT: 504,
}
ROBOT_ERROR_STATUS = 502
ROBOT_EVENT = 'robot'
RESULT_EVENT = 'result'


def api_error(error: FleetError) -> ApiError:
    """The HTTP answer of a FleetError: its code and message, the status of STATUS_OF_CODE."""
    code = error.code or RefusalCode.ROBOT_ERROR
    return ApiError(STATUS_OF_CODE.get(code, ROBOT_ERROR_STATUS), code, str(error))


def checked_answer(model: type[M], document: Any, robot_id: str) -> M:
    """A robot's reply as `model`; 502 `bad_reply` when it does not fit (it came from a robot
    over the broker)."""
    try:
        return model.model_validate(document)
    except ValidationError as error:
        message, _ = describe(error.errors())
        message = f'the reply of {robot_id} does not fit: {message}'
        raise ApiError(502, RefusalCode.BAD_REPLY, message) from None


def checked_robot_id(robot_id: str) -> str:
    """`robot_id` of a request's path; 422 naming it when it can name no robot (control
    characters, too long, a topic level or wildcard)."""
    if problem := robot_id_problem(robot_id):
        raise ApiError(422, RefusalCode.INVALID_REQUEST, problem, 'robot_id')
    return robot_id


class FleetLink(DoorLink):
    """The Fleet as the doors' handlers see it (use from the event loop)."""

    def __init__(self, fleet: Fleet, loop: asyncio.AbstractEventLoop) -> None:
        super().__init__(loop, 'console')
        self.fleet = fleet
        self._waiting_lock = threading.Lock()
        self._robots_changed: set[str] = set()
        """Ids of the robots changed since the streams were last offered their changes."""
        self._results: list[dict[str, Any]] = []
        """Results stored since then, in the order stored."""
        self._overflowed = False
        self._wake_due = False
        self._remove = fleet.on_change(self._on_change)

    def close(self) -> None:
        self._remove()
        super().close()

    def robot(self, robot_id: str) -> RobotState:
        """The robot of a request's path: 422 for an id that can name none, 404 if unknown."""
        robot = self.fleet.robot(checked_robot_id(robot_id))
        if robot is None:
            message = f'no robot {robot_id!r} is known on the broker'
            raise ApiError(404, RefusalCode.UNKNOWN_ROBOT, message, 'robot_id')
        return robot

    async def read(self, function: Callable[..., T], *args: Any, **kwargs: Any) -> T:
        """A read of the fleet history, in a read thread; 503 while the database is away."""
        try:
            return await self._in(self._reads, partial(function, *args, **kwargs))
        except DatabaseUnavailable as error:
            raise ApiError(503, RefusalCode.DATABASE_UNAVAILABLE, str(error)) from None

    async def start(self, function: Callable[..., T], *args: Any, **kwargs: Any) -> T:
        """A start on a robot (its reply awaited), in a start thread."""
        return await self._robot_call(self._starts, partial(function, *args, **kwargs))

    async def control(self, function: Callable[..., T], *args: Any, **kwargs: Any) -> T:
        """A stop, cancel, pause, ... (its reply awaited), in a thread no read or start takes."""
        return await self._robot_call(self._control, partial(function, *args, **kwargs))

    async def _robot_call(self, pool: ThreadPoolExecutor, call: Callable[[], T]) -> T:
        try:
            return await self._in(pool, call)
        except FleetError as error:
            raise api_error(error) from None

    # ---- event streams ------------------------------------------------------------------------

    def _on_change(self, change: Change) -> None:
        """On the Fleet's threads: note the change, wake the loop if it is not due already."""
        if not self._streams:  # no one to tell: a stream opened later starts with the robots
            return
        with self._waiting_lock:
            self._robots_changed.add(change.robot.robot_id)
            if change.result is not None:
                if len(self._results) < STREAM_QUEUE_MAX:
                    self._results.append(change.result)
                else:  # the loop has not taken them for that long: every stream starts over
                    self._overflowed = True
            wake, self._wake_due = not self._wake_due, True
        if wake:
            with contextlib.suppress(RuntimeError):  # the loop has closed: the console stops
                self._loop.call_soon_threadsafe(self._offer_changes)

    def _offer_changes(self) -> None:
        """On the loop: offer every stream the results stored and the robots changed."""
        with self._waiting_lock:
            robot_ids, self._robots_changed = self._robots_changed, set()
            results, self._results = self._results, []
            overflowed, self._overflowed = self._overflowed, False
            self._wake_due = False
        if overflowed:
            for stream in self._streams:
                stream.offer(EventStream.OVERFLOW, '{"message": "the console fell behind"}')
            return
        events = [(RESULT_EVENT, compact_json(result)) for result in results]
        for robot_id in sorted(robot_ids):
            robot = self.fleet.robot(robot_id)
            if robot is not None:
                events.append((ROBOT_EVENT, compact_json(robot.document())))
        for stream in list(self._streams):
            for kind, text in events:
                stream.offer(kind, text)


async def _link(request: Request) -> FleetLink:
    link: FleetLink = request.app.state.link
    return link


Link = Annotated[FleetLink, Depends(_link)]
"""A route's FleetLink (the app's, made at start-up)."""
