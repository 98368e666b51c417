"""What the doors' link to what they serve shares, the web gateway's to its Task Manager
(node_link.py) and the fleet console's to its Fleet: its blocking calls run in three pools of
threads, so that no kind of request waits behind another (reads; starts; control: stop, cancel,
pause, ...), and the event streams open, each fed from the event loop. No rclpy here."""

import asyncio
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

from fastapi import FastAPI
from fastapi.responses import StreamingResponse

from task_manager_web.event_stream import EventStream, event_lines

T = TypeVar('T')
READ_THREADS = 4
START_THREADS = 8
CONTROL_THREADS = 4
"""Control (stop, cancel, pause, ...): each holds its thread until its answer came."""
HELLO_EVENT = 'hello'
EVENT_STREAM_TYPE = 'text/event-stream'
EVENT_STREAM_ROUTE: dict[str, Any] = {
    'response_class': StreamingResponse,
    'responses': {200: {'content': {EVENT_STREAM_TYPE: {}}}},
}
"""What the route of an event stream answers, for its OpenAPI description."""


class DoorLink:
    """The pools and the event streams of a link (use from the event loop)."""

    def __init__(self, loop: asyncio.AbstractEventLoop, name: str) -> None:
        """`name`: the start of its threads' names (`web`: web_read_0, ...)."""
        self._loop = loop
        self._reads = ThreadPoolExecutor(READ_THREADS, f'{name}_read')
        self._starts = ThreadPoolExecutor(START_THREADS, f'{name}_start')
        self._control = ThreadPoolExecutor(CONTROL_THREADS, f'{name}_control')
        self._streams: set[EventStream] = set()

    def close(self) -> None:
        for pool in (self._reads, self._starts, self._control):
            pool.shutdown(wait=False, cancel_futures=True)

    async def _in(self, pool: ThreadPoolExecutor, call: Callable[[], T]) -> T:
        return await self._loop.run_in_executor(pool, call)

    def open_stream(self) -> EventStream:
        stream = EventStream()
        self._streams.add(stream)
        return stream

    def close_stream(self, stream: EventStream) -> None:
        self._streams.discard(stream)

    def end_streams(self, message: str) -> None:
        """End every event stream (the server stops): none holds the server's stop."""
        for stream in self._streams:
            stream.end(message)

    @property
    def stream_count(self) -> int:
        return len(self._streams)

    def event_response(self, hello: Callable[[], str]) -> StreamingResponse:
        """A new event stream as Server-Sent Events: `hello` (its JSON text, made once the
        stream is open, so that no change is missed in between), then every event offered to
        the stream."""
        stream = self.open_stream()
        return StreamingResponse(
            event_lines(stream, [(HELLO_EVENT, hello())], lambda: self.close_stream(stream)),
            media_type=EVENT_STREAM_TYPE,
            headers={'Cache-Control': 'no-store', 'X-Accel-Buffering': 'no'},
        )


def end_event_streams(app: FastAPI, message: str) -> None:
    """End the event streams of `app`'s link (`app.state.link`, once its lifespan has made
    it), each with a `bye` event saying `message`: its server stops."""
    link: DoorLink | None = getattr(app.state, 'link', None)
    if link is not None:
        link.end_streams(message)
