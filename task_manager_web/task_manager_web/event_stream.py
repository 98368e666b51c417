"""One client's event stream (Server-Sent Events): the events waiting for it, and the lines
sent. Shared by the web gateway and the fleet console (no rclpy here)."""

import asyncio
import json
from collections.abc import AsyncIterator, Callable, Iterable

KEEPALIVE_SEC = 15.0
"""An event stream idle this long gets a comment line, which also finds clients gone."""
STREAM_QUEUE_MAX = 10_000
"""Events a stream may have waiting; a client that falls this far behind is disconnected."""
BATCH_MAX = 200
"""Events waiting together sent in one piece at most."""
BATCH_MAX_CHARS = 262_144
"""Once the events taken for one piece hold this much text, no more are added (an event may
carry a result of up to a MiB: it goes alone)."""


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

    async def next_batch(
        self, limit: int = BATCH_MAX, max_chars: int = BATCH_MAX_CHARS
    ) -> list[tuple[str, str]]:
        """The next event, and those waiting behind it, until `limit` events or `max_chars` of
        text are taken: the last is the stream's end (overflow or bye) if one came, and nothing
        after it is taken."""
        batch = [await self._queue.get()]
        chars = len(batch[0][1])
        while (
            len(batch) < limit
            and chars < max_chars
            and batch[-1][0] not in ENDS
            and not self._queue.empty()
        ):
            batch.append(self._queue.get_nowait())
            chars += len(batch[-1][1])
        return batch


async def event_lines(
    stream: EventStream,
    first: Iterable[tuple[str, str]],
    close: Callable[[], None],
    keepalive_sec: float = KEEPALIVE_SEC,
) -> AsyncIterator[str]:
    """The stream's text: the `first` events (kind, JSON text), then the events as they come,
    those waiting together in one piece (one write to the client, not one per event; a comment
    line when idle for `keepalive_sec`), until the client goes, the stream overflows or is
    ended; `close()` at the end."""
    try:
        for kind, text in first:
            yield sse(kind, text)
        while True:
            try:
                async with asyncio.timeout(keepalive_sec):
                    batch = await stream.next_batch()
            except TimeoutError:
                yield ': keepalive\n\n'
                continue
            yield ''.join(sse(kind, text) for kind, text in batch)
            if batch[-1][0] in ENDS:
                return
    finally:
        close()


ENDS = (EventStream.OVERFLOW, EventStream.BYE)
"""The kinds of event that end a stream."""


def sse(kind: str, data: str) -> str:
    """One event of a Server-Sent Events stream."""
    return f'event: {kind}\ndata: {data}\n\n'
