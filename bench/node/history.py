"""The task history's cost and speed.

1. The store's cost: dispatch latency and burst throughput with the history in a file (the
   default) vs in memory only (`history_path: ""`), compared as node_settings.py says.
2. A query on a full store: the 100 newest results of one task out of 1,000,000, through
   /task_manager/query_task_history, vs the same query on a store of 1,000. The bench fills
   both files itself, through the store's own writing code (the node would take hours), then
   restarts the node on each, small and big alternating (ABBA). It prints how long filling
   took, the file size per million results and what the query costs inside the store alone.
"""

import os
import statistics
import time
from pathlib import Path
from typing import Any

from bench.harness import config
from bench.harness.context import BenchContext
from bench.harness.replies import BenchError, Reply, wait_reply
from bench.harness.report import Row
from bench.harness.stats import Summary, latency_ms, ratio
from bench.node.node_settings import Setting, compare
from task_manager.core.history.store import HistoryQuery, TaskHistory
from task_manager.core.names import QUERY_TASK_HISTORY_SERVICE
from task_manager.core.status import TaskStatus
from task_manager.core.task import TaskRecord
from task_manager.core.task_spec import InterfaceName, TaskKind, TaskSpec
from task_manager.rclpy_tools import qos
from task_manager_msgs.srv import QueryTaskHistory

HISTORY_IN_MEMORY = Setting('history in memory', {'history_path': ''})
HISTORY_IN_FILE = Setting('history in file', {})  # the default: a file (a new one per phase)

BIG_STORE = 1_000_000
SMALL_STORE = 1_000
TASK_NAMES = 10  # the stored results cycle through this many task names
QUERIED_TASK = 'bench/stored_3'
QUERY_LIMIT = 100
QUERY_TARGET_MS = 20.0
QUERY_PHASES = (False, True, True, False)  # big store?
QUERY_SAMPLES = 100  # per phase
QUERY_WARM_UP = 10
FILL_BATCH = 10_000
STORED_RESULT = {'sequence': [0, 1, 1, 2]}
STORED_DATA = '{"order": 3}'


def fill_store(path: Path, count: int) -> float:
    """Write `count` ended tasks (DONE, one ms apart, ending an hour ago) to a new history
    file; return the seconds it took."""
    started = time.perf_counter()
    interface = InterfaceName('test_msgs', TaskKind.ACTION, 'Fibonacci')
    specs = [
        TaskSpec(f'bench/stored_{n}', f'/bench/stored_{n}', interface) for n in range(TASK_NAMES)
    ]
    first = time.time() - 3600 - count * 1e-3
    store = TaskHistory(str(path))
    try:
        for index in range(count):
            at = first + index * 1e-3
            record = TaskRecord(
                f'stored-{index}',
                specs[index % TASK_NAMES],
                'CLOUD' if index % 3 else 'CLI',
                status=TaskStatus.DONE,
                result=STORED_RESULT,
                received_at=at,
                started_at=at,
                ended_at=at + 5e-4,
                task_data=STORED_DATA,
            )
            store.write(record)
            if index % FILL_BATCH == FILL_BATCH - 1:
                store.flush()
        store.flush()
    finally:
        store.close()
    return time.perf_counter() - started


def store_query_ms(path: Path) -> list[float]:
    """The query inside the store alone, in ms (the file opened by the bench)."""
    store = TaskHistory(str(path))
    query = HistoryQuery(task_name=QUERIED_TASK, limit=QUERY_LIMIT)
    samples = []
    try:
        for _ in range(QUERY_WARM_UP + QUERY_SAMPLES):
            started = time.perf_counter()
            rows = store.query(query)
            samples.append((time.perf_counter() - started) * 1e3)
            if len(rows) != QUERY_LIMIT:
                raise BenchError(f'store query: {len(rows)} rows, expected {QUERY_LIMIT}')
    finally:
        store.close()
    return samples[QUERY_WARM_UP:]


def _expect_newest(reply: Reply) -> None:
    tasks = reply.response.tasks
    sequences = [task.sequence for task in tasks]
    if len(tasks) != QUERY_LIMIT or any(t.task_name != QUERIED_TASK for t in tasks):
        raise BenchError(f'query: {len(tasks)} tasks, expected {QUERY_LIMIT} of {QUERIED_TASK}')
    if sequences != sorted(sequences, reverse=True):
        raise BenchError('query: not newest first')


def service_query_ms(ctx: BenchContext, samples: int) -> list[float]:
    """Round trips of the query through the node's service, in ms."""
    node = ctx.client.harness.node
    client: Any = node.create_client(
        QueryTaskHistory, QUERY_TASK_HISTORY_SERVICE, qos_profile=qos.DEEP_RELIABLE
    )
    request = QueryTaskHistory.Request(task_name=QUERIED_TASK, limit=QUERY_LIMIT)
    try:
        if not client.wait_for_service(timeout_sec=config.CONNECT_TIMEOUT_SEC):
            raise BenchError(f'{QUERY_TASK_HISTORY_SERVICE} not available')
        for _ in range(QUERY_WARM_UP):  # also waits for the reply path to match
            wait_reply(ctx.client.call(client, request), 'query warm-up')
        return [
            latency_ms(lambda: ctx.client.call(client, request), _expect_newest, 'query')
            for _ in range(samples)
        ]
    finally:
        node.destroy_client(client)


def query_benchmark(ctx: BenchContext) -> None:
    small_path, big_path = ctx.log_dir / 'history_small.sqlite', ctx.log_dir / 'history_big.sqlite'
    fill_store(small_path, SMALL_STORE)
    fill_sec = fill_store(big_path, BIG_STORE)
    megabytes = os.path.getsize(big_path) / 1e6
    in_store = store_query_ms(big_path)
    # key: big store?, value: round trips
    samples: dict[bool, list[float]] = {False: [], True: []}
    try:
        for index, big in enumerate(QUERY_PHASES):
            path, stored = (big_path, BIG_STORE) if big else (small_path, SMALL_STORE)
            print(f'[bench] history query phase {index + 1}: {stored} stored', flush=True)
            ctx.restart_node(
                f'task_manager_history_{index + 1}_{stored}',
                history_path=str(path),
                history_max_results=0,
                history_max_age_days=0,
                history_max_bytes=0,
            )
            samples[big] += service_query_ms(ctx, QUERY_SAMPLES)
    finally:
        ctx.restart_node()
    big_ms, small_ms = Summary.of(samples[True]), Summary.of(samples[False])
    ctx.report.add(
        Row(
            benchmark='history query',
            metric=(
                f'{QUERY_LIMIT} newest of one task, {BIG_STORE:,} stored, ms, med / p95, '
                f'n={big_ms.count}'
            ),
            measured=big_ms.text(),
            baseline=f'{small_ms.text()} {SMALL_STORE:,} stored',
            ratio=f'{ratio(big_ms.median, small_ms.median):.2f}x',
            target=f'< {QUERY_TARGET_MS:.0f} ms',
            met=big_ms.median < QUERY_TARGET_MS,
        )
    )
    ctx.report.note(
        f'history: filled {BIG_STORE:,} results in {fill_sec:.1f} s '
        f'({BIG_STORE / fill_sec:,.0f}/s, batches of {FILL_BATCH:,}); the file is '
        f'{megabytes * 1e6 / BIG_STORE:.0f} MB per million results; the query inside the '
        f'store alone: med {statistics.median(in_store):.2f} ms'
    )


def run(ctx: BenchContext) -> None:
    compare(ctx, HISTORY_IN_MEMORY, HISTORY_IN_FILE)
    query_benchmark(ctx)
