"""An event stream's text: events waiting together go out in one piece, in order, and nothing
after the stream's end (no ROS, no server: the stream and its generator alone)."""

import asyncio
from collections.abc import AsyncIterator

from task_manager_web.event_stream import (
    BATCH_MAX,
    BATCH_MAX_CHARS,
    EventStream,
    event_lines,
    sse,
)


def _pieces(stream: EventStream, offered: list[tuple[str, str]], count: int) -> list[str]:
    """The first `count` pieces of the stream's text once `offered` waits in it."""

    async def read() -> list[str]:
        for kind, text in offered:
            stream.offer(kind, text)
        lines: AsyncIterator[str] = event_lines(stream, [('hello', '{}')], lambda: None)
        return [await anext(lines) for _ in range(count)]

    return asyncio.run(asyncio.wait_for(read(), 5.0))


def test_events_waiting_together_go_out_in_one_piece_in_order() -> None:
    offered = [('task', f'{{"n": {n}}}') for n in range(5)]
    hello, events = _pieces(EventStream(), offered, 2)
    assert hello == sse('hello', '{}')
    assert events == ''.join(sse(kind, text) for kind, text in offered)


def test_a_piece_holds_at_most_batch_max_events_and_the_rest_follow() -> None:
    offered = [('task', f'{{"n": {n}}}') for n in range(BATCH_MAX + 3)]
    _, first, second = _pieces(EventStream(), offered, 3)
    assert first == ''.join(sse(kind, text) for kind, text in offered[:BATCH_MAX])
    assert second == ''.join(sse(kind, text) for kind, text in offered[BATCH_MAX:])


def test_a_piece_stops_growing_once_it_holds_batch_max_chars_of_text() -> None:
    big = '"' + 'x' * (BATCH_MAX_CHARS // 2) + '"'
    offered = [('task', big), ('task', big), ('task', '{"n": 3}')]
    _, first, second = _pieces(EventStream(), offered, 3)
    assert first == sse('task', big) + sse('task', big)
    assert second == sse('task', '{"n": 3}')


def test_the_stream_ends_with_its_bye_and_takes_nothing_after_it() -> None:
    stream = EventStream()
    stream.offer('task', '{"n": 1}')
    stream.end('the gateway stops')
    stream.offer('task', '{"n": 2}')

    async def read() -> list[str]:
        return [piece async for piece in event_lines(stream, [], lambda: None)]

    pieces = asyncio.run(asyncio.wait_for(read(), 5.0))
    assert pieces == [
        sse('task', '{"n": 1}') + sse(EventStream.BYE, '{"message": "the gateway stops"}')
    ]


def test_a_full_stream_sends_its_overflow_notice_alone_and_ends() -> None:
    stream = EventStream(max_queued=3)
    for n in range(4):
        stream.offer('task', f'{{"n": {n}}}')
    closed: list[bool] = []

    async def read() -> list[str]:
        return [piece async for piece in event_lines(stream, [], lambda: closed.append(True))]

    pieces = asyncio.run(asyncio.wait_for(read(), 5.0))
    assert len(pieces) == 1 and pieces[0].startswith(f'event: {EventStream.OVERFLOW}\n')
    assert closed == [True]


def test_an_idle_stream_gets_a_keepalive_line() -> None:
    async def read() -> str:
        lines = event_lines(EventStream(), [], lambda: None, keepalive_sec=0.05)
        return await anext(lines)

    assert asyncio.run(asyncio.wait_for(read(), 5.0)) == ': keepalive\n\n'
