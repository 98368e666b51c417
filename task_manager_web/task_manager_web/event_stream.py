"""One client's event stream (Server-Sent Events): the events waiting for it, and the lines
sent. Shared by the web gateway and the fleet console (no rclpy here)."""

import asyncio
import json
from collections.abc import AsyncIterator, Callable, Iterable

KEEPALIVE_SEC = 15.0
"""An event stream idle this long gets a comment line, which also finds clients gone."""
STREAM_QUEUE_MAX = 10_000
"""Events a stream may have waiting; a client that falls this far behind is disconnected."""


class EventStream:
    """The events waiting for one client of an event stream: (kind, JSON text) pairs."""

    OVERFLOW = 'overflow'
    BYE = 'bye'
    """The last event of a stream the server ends (it stops)."""

    def __init__(self, max_queued: int = STREAM_QUEUE_MAX) -> None:
        self._queue: asyncio.Queue[tuple[str, str]] = asyncio.Queue(max_queued)

    def offer(self, kind: str, text: str) -> None:
        """Queue an event; when full, drop what waits and queue the overflow notice instead."""
        try:
            self._queue.put_nowait((kind, text))
        except asyncio.QueueFull:
            while not self._queue.empty():
                self._queue.get_nowait()
            notice = {'message': f'more than {self._queue.maxsize} events waited: reconnect'}
            self._queue.put_nowait((self.OVERFLOW, json.dumps(notice)))

    def end(self, message: str) -> None:
        """End the stream after what waits: a `bye` event saying `message` (or, when full,
        the overflow notice, which ends it too)."""
        self.offer(self.BYE, json.dumps({'message': message}))

    async def next(self) -> tuple[str, str]:
        return await self._queue.get()


async def event_lines(
    stream: EventStream,
    first: Iterable[tuple[str, str]],
    close: Callable[[], None],
    keepalive_sec: float = KEEPALIVE_SEC,
) -> AsyncIterator[str]:
    """The stream's text: the `first` events (kind, JSON text), then each event as it comes
    (a comment line when idle for `keepalive_sec`), until the client goes, the stream
    overflows or is ended; `close()` at the end."""
    try:
        for kind, text in first:
            yield sse(kind, text)
        while True:
            try:
                kind, text = await asyncio.wait_for(stream.next(), keepalive_sec)
            except TimeoutError:
                yield ': keepalive\n\n'
                continue
            yield sse(kind, text)
            if kind in (EventStream.OVERFLOW, EventStream.BYE):
                return
    finally:
        close()


def sse(kind: str, data: str) -> str:
    """One event of a Server-Sent Events stream."""
    return f'event: {kind}\ndata: {data}\n\n'
