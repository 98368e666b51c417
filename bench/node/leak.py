"""Memory over many tasks: the node's RSS while LEAK_TASKS instant tasks run through it, in
bursts of LEAK_BURST sent at once, sampled every LEAK_SAMPLE_EVERY tasks. Growth after the
first sample taken WARM_UP_SEC after the first burst would be a leak: by then the node's
caches, the history's pages and the goals the ExecuteTask server keeps (config.KEPT_GOALS_SEC)
have reached their working size (at 500 tasks a second the first LEAK_SAMPLE_EVERY tasks take
6 s, and the RSS grew 7 % more until 10 s, then not at all: a warm-up the row took for a leak).
"""

import time

import psutil

from bench.harness import config
from bench.harness.client import task_status
from bench.harness.context import BenchContext
from bench.harness.replies import BenchError
from bench.harness.report import Row
from bench.harness.stats import last_reply_after
from task_manager.rclpy_tools.futures import result_of

MIB = 1024 * 1024
GROWTH_TARGET_PERCENT = 10.0
WARM_UP_SEC = config.KEPT_GOALS_SEC + 1.5


def burst(ctx: BenchContext) -> float:
    """LEAK_BURST instant tasks at once; seconds until the last result."""
    started = time.perf_counter()
    results = [
        ctx.client.send_task(config.FIBONACCI_TASK, config.FIBONACCI_DATA)
        for _ in range(config.LEAK_BURST)
    ]
    elapsed = last_reply_after(started, results, 'results of a leak-check burst')
    failed = sum(1 for future in results if task_status(result_of(future)) != 'DONE')
    if failed:
        raise BenchError(f'{failed} of {config.LEAK_BURST} tasks did not end DONE')
    return elapsed


def run(ctx: BenchContext) -> None:
    node = psutil.Process(ctx.node.pid)
    start_mib = node.memory_info().rss / MIB
    samples: list[tuple[int, float]] = []
    warm: list[tuple[int, float]] = []  # the samples taken once warmed up
    busy_sec = 0.0
    started = time.monotonic()
    for done in range(config.LEAK_BURST, config.LEAK_TASKS + 1, config.LEAK_BURST):
        busy_sec += burst(ctx)
        if done % config.LEAK_SAMPLE_EVERY == 0:
            samples.append((done, node.memory_info().rss / MIB))
            if time.monotonic() - started >= WARM_UP_SEC:
                warm.append(samples[-1])
    if len(warm) < 2:
        raise BenchError(f'the leak check needs two samples {WARM_UP_SEC:.0f} s after its start')
    (first_tasks, first_mib), (last_tasks, last_mib) = warm[0], warm[-1]
    growth = 100 * (last_mib - first_mib) / first_mib
    ctx.report.add(
        Row(
            benchmark='leak check',
            metric=f'node RSS MiB after {first_tasks:,} -> {last_tasks:,} instant tasks',
            measured=f'{first_mib:.0f} -> {last_mib:.0f} ({growth:+.1f} %)',
            baseline=f'{start_mib:.0f} before',
            target=f'growth < {GROWTH_TARGET_PERCENT:.0f} %',
            met=growth < GROWTH_TARGET_PERCENT,
        )
    )
    trail = ', '.join(f'{tasks // 1000}k: {mib:.0f}' for tasks, mib in samples)
    ctx.report.note(
        f'leak check: RSS MiB {trail}; {config.LEAK_TASKS:,} tasks in {busy_sec:.0f} s '
        f'({config.LEAK_TASKS / busy_sec:.0f} tasks/s); growth from the first sample '
        f'{WARM_UP_SEC:.0f} s in'
    )
