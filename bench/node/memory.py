"""Memory once tasks have ended: the RSS of the node and of the web gateway before and after
MEMORY_TASKS instant tasks started through the gateway (POST /api/tasks/start?wait=true from
MEMORY_CLIENTS connections at once, each task with a 250-character id, an event stream open
all along, as the dashboard keeps one), sampled once every task has ended and the node's
ExecuteTask server has dropped the goals it keeps (10 s). Each must be back within
MEMORY_GROWTH_TARGET_PERCENT of where it started: a finished task must leave nothing behind.

Where they started is measured after a warm-up of MEMORY_WARM_UP tasks (the first tasks load
modules and fill pools and caches of a fixed size), and shown beside the RSS before any task.
"""

import json
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

import httpx
import psutil
from task_manager_web.testing import GatewayProcess

from bench.gateways.web import HTTP_TIMEOUT_SEC, TimedConnection, running_gateway
from bench.harness import config
from bench.harness.context import BenchContext
from bench.harness.replies import BenchError
from bench.harness.report import Row

MIB = 1024 * 1024
LONG_ID = 'm' * 240
"""With a number: 250-character ids, as the attack probes sent."""


def rss_mib(pid: int) -> float:
    return float(psutil.Process(pid).memory_info().rss) / MIB


def run_tasks(gateway: GatewayProcess, first: int, count: int) -> None:
    """`count` instant tasks through the gateway from MEMORY_CLIENTS connections; all DONE."""
    body = {'task_name': config.FIBONACCI_TASK, 'task_data': json.loads(config.FIBONACCI_DATA)}
    numbers = iter(range(first, first + count))
    lock = threading.Lock()

    def client() -> int:
        timed = TimedConnection(gateway)
        done = 0
        try:
            while True:
                with lock:
                    number = next(numbers, None)
                if number is None:
                    return done
                task_id = f'{LONG_ID}{number:010d}'
                status, content = timed.post(
                    '/api/tasks/start?wait=true', {**body, 'task_id': task_id}
                )
                task = json.loads(content).get('task') or {}
                if status != 200 or task.get('status') != 'DONE':
                    raise BenchError(f'memory: task {number}: {status} {content[:200]!r}')
                done += 1
        finally:
            timed.close()

    with ThreadPoolExecutor(config.MEMORY_CLIENTS) as pool:
        done = sum(pool.map(lambda _: client(), range(config.MEMORY_CLIENTS)))
    if done != count:
        raise BenchError(f'memory: {done} of {count} tasks ended DONE')


@contextmanager
def open_stream(gateway: GatewayProcess) -> Iterator[list[int]]:
    """An event stream read all along; yields [the lines read so far]."""
    read = [0]
    stop = threading.Event()

    def reader() -> None:
        headers = {'Authorization': f'Bearer {gateway.token}'}
        with (
            httpx.Client(base_url=gateway.url, headers=headers, timeout=None) as http,
            http.stream('GET', '/api/events') as stream,
        ):
            for _ in stream.iter_lines():
                read[0] += 1
                if stop.is_set():
                    return

    thread = threading.Thread(target=reader, name='memory-stream', daemon=True)
    thread.start()
    try:
        yield read
    finally:
        stop.set()  # the reader returns at its next line (a keep-alive comment at the latest)


def settled_rss(
    ctx: BenchContext, gateway: GatewayProcess, http: httpx.Client
) -> tuple[float, ...]:
    """The RSS of the node and the gateway once no task is active and the kept goals are gone."""
    deadline = time.monotonic() + HTTP_TIMEOUT_SEC
    while http.get('/api/active').json():
        if time.monotonic() > deadline:
            raise BenchError('memory: tasks still active after the last one ended')
        time.sleep(0.1)
    ctx.wait_kept_goals_gone()
    return rss_mib(ctx.node.pid), rss_mib(gateway.process.pid)


def run(ctx: BenchContext) -> None:
    with running_gateway(ctx) as (gateway, http), open_stream(gateway) as lines:
        before = rss_mib(ctx.node.pid), rss_mib(gateway.process.pid)
        run_tasks(gateway, 0, config.MEMORY_WARM_UP)
        start = settled_rss(ctx, gateway, http)
        began = time.perf_counter()
        run_tasks(gateway, config.MEMORY_WARM_UP, config.MEMORY_TASKS)
        busy_sec = time.perf_counter() - began
        end = settled_rss(ctx, gateway, http)
    for name, was, started, ended in zip(('node', 'web gateway'), before, start, end, strict=True):
        growth = 100 * (ended - started) / started
        ctx.report.add(
            Row(
                benchmark='memory',
                metric=f'{name} RSS MiB after {config.MEMORY_TASKS:,} web tasks, once ended',
                measured=f'{started:.0f} -> {ended:.0f} ({growth:+.1f} %)',
                baseline=f'{was:.0f} before any task',
                target=f'growth < {config.MEMORY_GROWTH_TARGET_PERCENT:.0f} %',
                met=growth < config.MEMORY_GROWTH_TARGET_PERCENT,
            )
        )
    ctx.report.note(
        f'memory: {config.MEMORY_TASKS:,} tasks through the web gateway in {busy_sec:.0f} s '
        f'from {config.MEMORY_CLIENTS} connections ({config.MEMORY_TASKS / busy_sec:.0f} '
        f'tasks/s), an event stream open ({lines[0]:,} lines read)'
    )
