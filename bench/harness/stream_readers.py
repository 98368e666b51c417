"""`python -m bench.harness.stream_readers URL TOKEN COUNT`: COUNT open /api/events streams.

Prints `open` once every stream got its `hello`; then, for each line of task ids (a JSON
list) read from stdin, waits until every stream got the RECEIVED, STARTED and ENDED events of
each (at most EVENTS_TIMEOUT_SEC) and prints `{"complete": streams that did}`.
"""

import asyncio
import json
import sys
import threading

import httpx

EVENTS_PER_TASK = ('RECEIVED', 'STARTED', 'ENDED')
EVENTS_TIMEOUT_SEC = 60.0
OPEN_TIMEOUT_SEC = 60.0
CLOSE_TIMEOUT_SEC = 30.0


def readers_command(url: str, token: str, count: int) -> list[str]:
    """The command that opens `count` streams in a process of its own, as browsers would."""
    return [sys.executable, '-m', __name__, url, token, str(count)]


class EventStreams:
    """`count` open /api/events streams, each recording the (event, task id) pairs it got."""

    def __init__(self, url: str, token: str, count: int) -> None:
        self._url = url
        self._token = token
        self.seen: list[set[tuple[str, str]]] = [set() for _ in range(count)]
        self._opened = 0
        self._changed = threading.Condition()
        self._loop = asyncio.new_event_loop()
        self._stopping: asyncio.Event | None = None
        self._thread = threading.Thread(target=self._loop.run_until_complete, args=(self._main(),))
        self._thread.start()

    async def _main(self) -> None:
        self._stopping = asyncio.Event()
        limits = httpx.Limits(max_connections=len(self.seen) + 10)
        params = {'token': self._token}
        async with httpx.AsyncClient(base_url=self._url, limits=limits, timeout=None) as client:
            readers = [asyncio.create_task(self._read(client, params, seen)) for seen in self.seen]
            await self._stopping.wait()
            for reader in readers:
                reader.cancel()
            await asyncio.gather(*readers, return_exceptions=True)

    async def _read(
        self, client: httpx.AsyncClient, params: dict[str, str], seen: set[tuple[str, str]]
    ) -> None:
        async with client.stream('GET', '/api/events', params=params) as response:
            kind = ''
            async for line in response.aiter_lines():
                if line.startswith('event: '):
                    kind = line[len('event: ') :]
                elif line.startswith('data: ') and kind == 'hello':
                    self._count_opened()
                elif line.startswith('data: ') and kind == 'task':
                    event = json.loads(line[len('data: ') :])
                    self._record(seen, (event['event'], event['task']['task_id']))

    def _count_opened(self) -> None:
        with self._changed:
            self._opened += 1
            self._changed.notify_all()

    def _record(self, seen: set[tuple[str, str]], pair: tuple[str, str]) -> None:
        with self._changed:
            seen.add(pair)
            self._changed.notify_all()

    def wait_open(self, timeout_sec: float) -> None:
        with self._changed:
            if not self._changed.wait_for(lambda: self._opened >= len(self.seen), timeout_sec):
                raise TimeoutError(f'{self._opened} of {len(self.seen)} event streams opened')

    def wait_for(self, expected: set[tuple[str, str]], timeout_sec: float) -> int:
        """How many streams got every expected event within `timeout_sec`."""
        with self._changed:
            self._changed.wait_for(lambda: all(expected <= s for s in self.seen), timeout_sec)
            return sum(expected <= s for s in self.seen)

    def close(self) -> None:
        if self._stopping is not None:
            self._loop.call_soon_threadsafe(self._stopping.set)
        self._thread.join(CLOSE_TIMEOUT_SEC)
        self._loop.close()


def main() -> None:
    url, token, count = sys.argv[1], sys.argv[2], int(sys.argv[3])
    streams = EventStreams(url, token, count)
    try:
        streams.wait_open(OPEN_TIMEOUT_SEC)
        print('open', flush=True)
        for line in sys.stdin:
            expected = {
                (event, task_id) for task_id in json.loads(line) for event in EVENTS_PER_TASK
            }
            print(
                json.dumps({'complete': streams.wait_for(expected, EVENTS_TIMEOUT_SEC)}), flush=True
            )
    finally:
        streams.close()


if __name__ == '__main__':
    main()
