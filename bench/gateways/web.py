"""The web gateway: start-to-result of an instant task through `POST /api/tasks/start?wait=true`
vs through ExecuteTask directly (interleaved, in one run), and 200 open event streams while
tasks run (every stream must get every event).

The gateway runs as users run it (`task-manager-web`, its own process, in the bench's ROS
domain); the timed requests go through one kept-alive connection of the standard library's
http.client (see TimedConnection), as a UI keeps one. The streams are
read by another process (bench/harness/stream_readers.py), as browsers would.
"""

import http.client
import json
import socket
import statistics
import subprocess
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any
from urllib.parse import urlsplit

import httpx
from task_manager_web.testing import GatewayProcess

from bench.harness import config
from bench.harness.context import BenchContext
from bench.harness.replies import BenchError
from bench.harness.report import Row
from bench.harness.stats import Summary
from bench.harness.stream_readers import EVENTS_PER_TASK, readers_command
from bench.node.dispatch import interleaved

ADDED_TARGET_MS = 3.0
NO_DELAY = (socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
HTTP_TIMEOUT_SEC = 30.0


@contextmanager
def running_gateway(ctx: BenchContext) -> Iterator[tuple[GatewayProcess, httpx.Client]]:
    token_file = ctx.log_dir / 'web_token'
    token_file.write_text('bench-token-0123456789\n')
    gateway = GatewayProcess(token_file, nice=None)  # as users start it
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


class TimedConnection:
    """The timed requests' client: one kept-alive connection of the standard library's
    http.client, with TCP_NODELAY as browsers set it.

    A request costs httpx about 0.4 ms more than http.client (GET /api/health: raw socket
    0.22 ms, http.client 0.53 ms, httpx 0.93 ms, 2026-11-26): measured with httpx, that was
    counted as time the gateway adds.
    """

    def __init__(self, gateway: GatewayProcess) -> None:
        url = urlsplit(gateway.url)
        self._connection = http.client.HTTPConnection(
            url.hostname or '127.0.0.1', url.port, HTTP_TIMEOUT_SEC
        )
        self._headers = {
            'Authorization': f'Bearer {gateway.token}',
            'Content-Type': 'application/json',
        }
        self.reconnect()

    def reconnect(self) -> None:
        """A new connection: after a pause longer than the gateway keeps an idle one (5 s)."""
        self._connection.close()
        self._connection.connect()
        assert self._connection.sock is not None
        self._connection.sock.setsockopt(*NO_DELAY)

    def post(self, path: str, body: dict[str, Any]) -> tuple[int, bytes]:
        self._connection.request('POST', path, json.dumps(body), self._headers)
        response = self._connection.getresponse()
        return response.status, response.read()

    def close(self) -> None:
        self._connection.close()


def web_task_ms(timed: TimedConnection) -> float:
    """Round trip of the bench's instant task through the gateway; it must end DONE."""
    body = {'task_name': config.FIBONACCI_TASK, 'task_data': json.loads(config.FIBONACCI_DATA)}
    started = time.perf_counter()
    status, content = timed.post('/api/tasks/start?wait=true', body)
    elapsed_ms = (time.perf_counter() - started) * 1000
    task = json.loads(content).get('task') or {}
    if status != 200 or task.get('status') != 'DONE':
        raise BenchError(f'web task: {status} {content[:200]!r}')
    return elapsed_ms


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
        timed = TimedConnection(gateway)
        try:
            interleaved(lambda: web_task_ms(timed), ctx.fibonacci_task_ms, config.WARM_UP_SAMPLES)
            ctx.settle()
            timed.reconnect()
            quiet = interleaved(
                lambda: web_task_ms(timed), ctx.fibonacci_task_ms, config.WEB_SAMPLES
            )
            ctx.report.add(_added_row(*quiet, 'start?wait=true'))
            _streams(ctx, gateway, http, timed)
        finally:
            timed.close()


def _streams(
    ctx: BenchContext, gateway: GatewayProcess, http: httpx.Client, timed: TimedConnection
) -> None:
    count = config.WEB_STREAMS
    readers = subprocess.Popen(
        readers_command(gateway.url, gateway.token, count),
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert readers.stdin is not None and readers.stdout is not None
    try:
        if readers.stdout.readline().strip() != 'open':
            raise BenchError(f'the {count} event streams did not open')
        ctx.settle()
        timed.reconnect()
        busy = interleaved(
            lambda: web_task_ms(timed), ctx.fibonacci_task_ms, config.WEB_STREAM_TASKS
        )
        since = time.perf_counter()
        ended = http.get('/api/history', params={'limit': len(busy[0]) * 2}).json()
        readers.stdin.write(json.dumps([task['task_id'] for task in ended]) + '\n')
        readers.stdin.flush()
        complete = json.loads(readers.stdout.readline())['complete']
        drained_sec = time.perf_counter() - since
    finally:
        readers.stdin.close()
        readers.wait(HTTP_TIMEOUT_SEC)
    events = len(ended) * len(EVENTS_PER_TASK)
    ctx.report.add(
        _added_row(*busy, f'start?wait=true, {count} event streams open'),
        Row(
            benchmark='web event streams',
            metric=f'streams that got all {events} events of {len(ended)} tasks',
            measured=f'{complete} of {count}',
            baseline='',
            target=f'{count} of {count}',
            met=complete == count,
        ),
    )
    ctx.report.note(
        f'web: {count} streams (read by another process) had every event {drained_sec:.2f} s '
        f'after the last task ended; median round trip with them open '
        f'{statistics.median(busy[0]):.2f} ms'
    )
