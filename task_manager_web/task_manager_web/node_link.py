"""The gateway's link to the Task Manager: one TaskManagerClient, awaitable from asyncio.

The client is thread-based (its executor spins in a thread of its own): its blocking calls
run in worker threads, and what it reports on its executor thread (task events, the node
coming and going) is handed to the event loop with `call_soon_threadsafe`, one wake-up for
what came meanwhile. Each event is turned into JSON once, then offered to every open event
stream; with no stream open, it is not turned into anything. When events went missing (the
client fell behind the node), every open stream ends with an `overflow` event after what it
has: a page that gets one opens the stream again and starts from the tasks as they are.

The blocking calls have three pools of threads, so that no kind of request waits behind
another: reads, starts, and control (stop, cancel, pause, resume, schedule changes). A flood
of reads held up a cancel for seconds in the one small pool all shared (asyncio's default).
Reads are bounded per client before they get here (read_bound.py).
"""

import asyncio
import contextlib
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from typing import Annotated, Any, TypeVar

from fastapi import Depends, Request

from task_manager.client import TaskEvent, TaskHandle, TaskManagerClient, TaskResult
from task_manager.core.errors import TaskManagerUnavailable
from task_manager.core.text.json_text import compact_json
from task_manager.gateway.documents import event_json
from task_manager_web.door_link import DoorLink
from task_manager_web.event_stream import EventStream

T = TypeVar('T')
NOT_CONNECTED = (
    'the Task Manager is not reachable: no /task_manager node answers in this ROS domain '
    '(is it running, with the same ROS_DOMAIN_ID?)'
)


class NodeLink(DoorLink):
    """The Task Manager as the gateway's handlers see it (use from the event loop)."""

    def __init__(self, client: TaskManagerClient, loop: asyncio.AbstractEventLoop) -> None:
        super().__init__(loop, 'web')
        self.client = client
        # (kind, JSON text) from the client's threads, not yet offered to the streams
        self._waiting: list[tuple[str, str]] = []
        self._wake_due = False
        self._waiting_lock = threading.Lock()
        self._unsubscribe = [
            client.on_task_event(self._on_event),
            client.on_connection_change(self._on_connection_change),
            client.on_events_lost(self._on_events_lost),
        ]

    def close(self) -> None:
        for unsubscribe in self._unsubscribe:
            unsubscribe()
        super().close()

    @property
    def connected(self) -> bool:
        return self.client.connected

    @property
    def events_connected(self) -> bool:
        """Whether the node's task events reach the gateway (they can come a moment after the
        active list, or never when the node publishes none)."""
        return self.client.events_connected

    def require_connected(self) -> None:
        """Fail at once (TaskManagerUnavailable) rather than wait for a node that is not there."""
        if not self.client.connected:
            raise TaskManagerUnavailable(NOT_CONNECTED)

    async def read(self, function: Callable[..., T], *args: Any, **kwargs: Any) -> T:
        """A blocking client call that reads, in a read thread; only while a Task Manager is
        there."""
        self.require_connected()
        return await self._in(self._reads, partial(function, *args, **kwargs))

    async def start(self, function: Callable[..., T], *args: Any, **kwargs: Any) -> T:
        """A client call that sends a goal (a start), in a start thread; see `_send`."""
        return await self._send(self._starts, function, *args, **kwargs)

    async def control(self, function: Callable[..., T], *args: Any, **kwargs: Any) -> T:
        """Stop, cancel, pause, resume or a schedule's change, in a thread of their own that no
        read or start can take."""
        return await self._send(self._control, function, *args, **kwargs)

    async def _send(
        self, pool: ThreadPoolExecutor, function: Callable[..., T], *args: Any, **kwargs: Any
    ) -> T:
        """A call that sends a goal: once the ExecuteTask server is matched.

        The node's topics can match before its action server does; a goal sent before then
        would be lost. Once matched, the wait returns at once.
        """
        self.require_connected()

        def when_available() -> T:
            self.client.wait_until_available()
            return function(*args, **kwargs)

        return await self._in(pool, when_available)

    async def result(self, handle: TaskHandle, timeout_sec: float) -> TaskResult | None:
        """The task's result once it ends; None if it has not within `timeout_sec`."""
        ended: asyncio.Future[None] = self._loop.create_future()

        def on_done(_: object) -> None:
            self._loop.call_soon_threadsafe(_set_done, ended)

        handle.result_future.add_done_callback(on_done)
        if not handle.done():
            try:
                await asyncio.wait_for(asyncio.shield(ended), timeout_sec)
            except TimeoutError:
                return None
        return handle.result_future.result()

    # ---- from the client's executor thread --------------------------------------------------

    def _on_event(self, event: TaskEvent) -> None:
        # no stream open, no one to tell: a stream opened later starts with what it reads
        if self._streams:
            self._hand_over('task', compact_json(event_json(event)))

    def _on_events_lost(self, batches: int) -> None:
        if not self._streams:
            return
        if not batches:  # the events reached the gateway a moment after the node did (it
            # started again): a page reads its tasks again on a connection, as it did a moment
            # ago, and keeps its stream
            self._on_connection_change(self.connected)
            return
        notice = {
            'message': f'{batches} batch(es) of task events went missing (the gateway fell '
            'behind the Task Manager): reconnect'
        }
        self._hand_over(EventStream.OVERFLOW, compact_json(notice))

    def _on_connection_change(self, connected: bool) -> None:
        self._hand_over('connection', compact_json({'connected': connected}))

    def _hand_over(self, kind: str, text: str) -> None:
        """Queue for the streams; the event loop is woken only if it is not already due to
        take what waits (a burst of events costs one wake-up and one switch of threads, not
        one per event)."""
        with self._waiting_lock:
            self._waiting.append((kind, text))
            wake, self._wake_due = not self._wake_due, True
        if wake:
            with contextlib.suppress(RuntimeError):  # the loop has closed: the gateway stops
                self._loop.call_soon_threadsafe(self._broadcast_waiting)

    def _broadcast_waiting(self) -> None:
        with self._waiting_lock:
            waiting, self._waiting, self._wake_due = self._waiting, [], False
        for kind, text in waiting:
            for stream in self._streams:
                stream.offer(kind, text)


def _set_done(future: asyncio.Future[None]) -> None:
    if not future.done():
        future.set_result(None)


async def _link(request: Request) -> NodeLink:
    link: NodeLink = request.app.state.link
    return link


Link = Annotated[NodeLink, Depends(_link)]
"""A route's NodeLink (the app's, made at start-up)."""
