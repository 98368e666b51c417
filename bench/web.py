"""The web gateway: start-to-result of an instant task through `POST /api/tasks/start?wait=true`
vs through ExecuteTask directly (interleaved, in one run), and 200 open event streams while
tasks run (every stream must get every event).

The gateway runs as users run it (`task-manager-web`, its own process, in the bench's ROS
domain); the bench's HTTP client keeps one connection alive, as a UI does. The streams are
read by an asyncio loop in a thread of the bench process.
"""

import asyncio
import json
import socket
import statistics
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

import httpx
from task_manager_web.testing import GatewayProcess

from bench import config
from bench.context import BenchContext
from bench.dispatch import interleaved
from bench.replies import BenchError
from bench.report import Row
from bench.stats import Summary

ADDED_TARGET_MS = 3.0
NO_DELAY = (socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
HTTP_TIMEOUT_SEC = 30.0
STREAMS_OPEN_TIMEOUT_SEC = 60.0
EVENTS_TIMEOUT_SEC = 60.0
# each instant task: RECEIVED, STARTED and ENDED
EVENTS_PER_TASK = ('RECEIVED', 'STARTED', 'ENDED')


@contextmanager
def running_gateway(ctx: BenchContext) -> Iterator[tuple[GatewayProcess, httpx.Client]]:
    token_file = ctx.log_dir / 'web_token'
    token_file.write_text('bench-token\n')
    gateway = GatewayProcess(token_file)
    headers = {'Authorization': f'Bearer {gateway.token}'}
    try:
        # TCP_NODELAY, as browsers set it: else the body of a POST waits for the ACK of its
        # headers, which the server delays by 40 ms (Nagle and delayed ACKs)
        transport = httpx.HTTPTransport(socket_options=[NO_DELAY])
        with httpx.Client(
            base_url=gateway.url, headers=headers, timeout=HTTP_TIMEOUT_SEC, transport=transport
        ) as http:
            deadline = time.monotonic() + HTTP_TIMEOUT_SEC
            while not http.get('/api/health').json()['connected']:
                if time.monotonic() > deadline:
                    raise BenchError('the gateway did not reach the node')
                threading.Event().wait(0.05)
            yield gateway, http
    finally:
        gateway.stop()


def web_task_ms(http: httpx.Client) -> float:
    """Round trip of the bench's instant task through the gateway; it must end DONE."""
    body = {'task_name': config.FIBONACCI_TASK, 'task_data': json.loads(config.FIBONACCI_DATA)}
    started = time.perf_counter()
    response = http.post('/api/tasks/start', params={'wait': 'true'}, json=body)
    elapsed_ms = (time.perf_counter() - started) * 1000
    task = response.json().get('task') or {}
    if response.status_code != 200 or task.get('status') != 'DONE':
        raise BenchError(f'web task: {response.status_code} {response.text[:200]}')
    return elapsed_ms


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
                raise BenchError(f'{self._opened} of {len(self.seen)} event streams opened')

    def wait_for(self, expected: set[tuple[str, str]], timeout_sec: float) -> int:
        """How many streams got every expected event within `timeout_sec`."""
        with self._changed:
            self._changed.wait_for(lambda: all(expected <= s for s in self.seen), timeout_sec)
            return sum(expected <= s for s in self.seen)

    def close(self) -> None:
        if self._stopping is not None:
            self._loop.call_soon_threadsafe(self._stopping.set)
        self._thread.join(HTTP_TIMEOUT_SEC)
        self._loop.close()


def _added_row(web_ms: list[float], direct_ms: list[float], label: str) -> Row:
    web, direct = Summary.of(web_ms), Summary.of(direct_ms)
    added = web.median - direct.median
    return Row(
        benchmark=f'web {label}',
        metric=f'round trip ms, med / p95, n={web.count}',
        measured=web.text(),
        baseline=f'{direct.text()} ExecuteTask',
        ratio=f'+{added:.2f} ms',
        target=f'<= +{ADDED_TARGET_MS} ms',
        met=added <= ADDED_TARGET_MS,
    )


def run(ctx: BenchContext) -> None:
    with running_gateway(ctx) as (gateway, http):
        interleaved(lambda: web_task_ms(http), ctx.fibonacci_task_ms, config.WARM_UP_SAMPLES)
        ctx.settle()
        quiet = interleaved(lambda: web_task_ms(http), ctx.fibonacci_task_ms, config.WEB_SAMPLES)
        ctx.report.add(_added_row(*quiet, 'start?wait=true'))
        _streams(ctx, gateway, http)


def _streams(ctx: BenchContext, gateway: GatewayProcess, http: httpx.Client) -> None:
    count = config.WEB_STREAMS
    streams = EventStreams(gateway.url, gateway.token, count)
    try:
        streams.wait_open(STREAMS_OPEN_TIMEOUT_SEC)
        ctx.settle()
        busy = interleaved(
            lambda: web_task_ms(http), ctx.fibonacci_task_ms, config.WEB_STREAM_TASKS
        )
        since = time.perf_counter()
        ended = http.get('/api/history', params={'limit': len(busy[0]) * 2}).json()
        expected = {(event, task['task_id']) for task in ended for event in EVENTS_PER_TASK}
        complete = streams.wait_for(expected, EVENTS_TIMEOUT_SEC)
        drained_sec = time.perf_counter() - since
    finally:
        streams.close()
    ctx.report.add(
        _added_row(*busy, f'start?wait=true, {count} event streams open'),
        Row(
            benchmark='web event streams',
            metric=f'streams that got all {len(expected)} events of {len(ended)} tasks',
            measured=f'{complete} of {count}',
            baseline='',
            target=f'{count} of {count}',
            met=complete == count,
        ),
    )
    ctx.report.note(
        f'web: {count} streams had every event {drained_sec:.2f} s after the last task ended; '
        f'median round trip with them open {statistics.median(busy[0]):.2f} ms'
    )
