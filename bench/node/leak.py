"""Memory over many tasks: the node's RSS while LEAK_TASKS instant tasks run through it, in
bursts of LEAK_BURST sent at once, sampled every LEAK_SAMPLE_EVERY tasks. Growth after the
first sample (by then the node's caches, the history's pages and the goals the ExecuteTask
server keeps for 10 s have reached their working size) would be a leak.
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
    busy_sec = 0.0
    for done in range(config.LEAK_BURST, config.LEAK_TASKS + 1, config.LEAK_BURST):
        busy_sec += burst(ctx)
        if done % config.LEAK_SAMPLE_EVERY == 0:
            samples.append((done, node.memory_info().rss / MIB))
    if len(samples) < 2:
        raise BenchError('the leak check needs at least two samples')
    (first_tasks, first_mib), (last_tasks, last_mib) = samples[0], samples[-1]
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
        f'({config.LEAK_TASKS / busy_sec:.0f} tasks/s)'
    )
