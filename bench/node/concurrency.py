"""Concurrency: a thousand long-running tasks active at once.

Measured: the time until all are IN_PROGRESS (vs the time the hold server takes to accept
the same goals sent directly), the node's threads and RSS, the time until all results are in
once the server ends them, and the cost of one /task_manager/active_tasks publication at
that size, three ways:
- in the node: when a task ends it publishes the list with the task's final status and at
  once the list without it; the interval between the two (their DDS source timestamps) is
  one build and publication of the list, measured for instant tasks run while all the held
  tasks are active, vs while nothing else is;
- the round trip of such an instant task vs idle: three publications (IN_PROGRESS, final
  status, removal) plus whatever else grows with the active tasks;
- building and publishing the same message in the bench process, as the node does it.
"""

import itertools
import time
from dataclasses import dataclass
from typing import Any

from rclpy.serialization import serialize_message
from rclpy.task import Future
from test_msgs.action import Fibonacci

from bench.harness import config
from bench.harness.client import BENCH_SOURCE, ActiveTasksWatcher, Publication, task_status
from bench.harness.context import BenchContext, succeeded
from bench.harness.processes import ResourceSampler
from bench.harness.replies import BenchError
from bench.harness.report import Row
from bench.harness.stats import Summary, last_reply_after, ratio
from bench.harness.wake_ups import CpuUse, cpu_use, wake_up_context
from task_manager.rclpy_tools import qos
from task_manager.rclpy_tools.futures import result_of
from task_manager_msgs.msg import ActiveTask, ActiveTaskArray

THREAD_GROWTH_ALLOWED = 2
# 1,000 tasks each woken once a second would cost far more than this in Python
WAITING_CPU_TARGET_PERCENT = 2.0
# issue 16: the cost of a task must not grow with the tasks around it
RAMP_TARGET = 2.0
LOADED_ROUND_TRIP_TARGET = 2.0
PUBLICATION_COPY_TOPIC = '/bench/active_tasks_copy'
MIB = 1024 * 1024


@dataclass(frozen=True)
class Loaded:
    """Instant tasks run one after another: round trips, and publication intervals."""

    round_trip_ms: list[float]
    publication_ms: list[float]


@dataclass(frozen=True)
class HoldRun:
    """Seconds until all goals were accepted/IN_PROGRESS, and from release to all results."""

    ramp_sec: float
    drain_sec: float
    waiting_cpu: CpuUse | None = None
    """The node's CPU while every task waited on its server (through the manager only)."""


def direct_hold(ctx: BenchContext, count: int) -> HoldRun:
    """The baseline: the same goals sent to the hold server itself."""
    accepted: list[Future[Any]] = [Future() for _ in range(count)]
    started = time.perf_counter()
    results = [ctx.client.hold.send_goal(Fibonacci.Goal(order=0), a) for a in accepted]
    ramp_sec = last_reply_after(started, accepted, 'direct goals accepted')
    released = time.perf_counter()
    ctx.client.release(ctx.client.release_goals, 'release of the held goals')
    drain_sec = last_reply_after(released, results, 'direct results')
    failed = sum(1 for future in results if not succeeded(result_of(future)))
    if failed:
        raise BenchError(f'{failed} of {count} goals sent directly did not succeed')
    return HoldRun(ramp_sec, drain_sec)


def managed_hold(
    ctx: BenchContext, watcher: ActiveTasksWatcher, count: int
) -> tuple[HoldRun, Loaded]:
    """The held tasks through the manager; also instant tasks while they all run."""
    started = time.perf_counter()
    results = [
        ctx.client.send_task(config.HOLD_TASK, config.FIBONACCI_DATA, f'held-{index:04d}')
        for index in range(count)
    ]
    ramp_sec = watcher.wait_in_progress(count, config.BURST_TIMEOUT_SEC) - started
    # measured unprofiled: py-spy stops the node at each of its 400 samples a second, which
    # cost it 10-20 % of a core here (1.2-3 % without)
    waiting_cpu = cpu_use(ctx.node.pid, config.WAITING_CPU_SEC)
    if ctx.profiling:
        with ctx.profiled(f'{count} tasks waiting on their server'):
            time.sleep(config.WAITING_CPU_SEC)
    loaded = instant_tasks(ctx, watcher, count)
    if ctx.profiling:
        with ctx.profiled(f'{count} tasks active: {config.LOADED_SAMPLES} more instant tasks'):
            for _ in range(config.LOADED_SAMPLES):
                ctx.fibonacci_task_ms()
    released = time.perf_counter()
    ctx.client.release(ctx.client.release_goals, 'release of the held goals')
    drain_sec = last_reply_after(released, results, 'results of the held tasks')
    failed = sum(1 for future in results if task_status(result_of(future)) != 'DONE')
    if failed:
        raise BenchError(f'{failed} of {count} held tasks did not end DONE')
    return HoldRun(ramp_sec, drain_sec, waiting_cpu), loaded


def instant_tasks(ctx: BenchContext, watcher: ActiveTasksWatcher, in_progress: int) -> Loaded:
    """Instant tasks one after another beside `in_progress` others: at least LOADED_SAMPLES,
    and more (up to MAX_LOADED_SAMPLES) until MIN_PUBLICATION_GAPS lists were seen in pairs.

    Beside a large list the node publishes at most 10 times a second, so 20 tasks of 5 ms
    may end within one publication (or none, if the timer fell while one was in progress).
    """
    watcher.take_history()
    round_trip_ms: list[float] = []
    history: list[Publication] = []
    while len(round_trip_ms) < config.LOADED_SAMPLES or (
        len(publication_gaps_ms(history, in_progress)) < config.MIN_PUBLICATION_GAPS
        and len(round_trip_ms) < config.MAX_LOADED_SAMPLES
    ):
        round_trip_ms.append(ctx.fibonacci_task_ms())
        history += watcher.take_history()
    return Loaded(round_trip_ms, publication_gaps_ms(history, in_progress))


def publication_gaps_ms(history: list[Publication], in_progress: int) -> list[float]:
    """Intervals (ms, DDS source timestamps) between a task's last two publications.

    When a task ends the node publishes the list with its final status, then at once the
    list without it: the interval is one build and publication of a list of that size.
    Only pairs listing at least `in_progress` tasks, the same number in both, are taken (one
    more is the next instant task, started before the list went out).
    """
    return [
        (removal.source_ns - final.source_ns) / 1e6
        for final, removal in itertools.pairwise(history)
        if final.lists_done
        and not removal.lists_done
        and final.in_progress == removal.in_progress >= in_progress
    ]


def publication_copy(ctx: BenchContext, count: int) -> tuple[Summary, int]:
    """Build and publish a list of `count` active tasks as the node does; ms, and its size."""
    node = ctx.client.harness.node
    publisher = node.create_publisher(ActiveTaskArray, PUBLICATION_COPY_TOPIC, qos.ACTIVE_TASKS)
    ids = [f'held-{index:04d}' for index in range(count)]
    samples: list[float] = []
    message = ActiveTaskArray()
    try:
        for _ in range(config.PUBLICATION_SAMPLES):
            started = time.perf_counter()
            message = ActiveTaskArray(
                active_tasks=[
                    ActiveTask(
                        task_id=task_id,
                        task_name=config.HOLD_TASK,
                        task_status='IN_PROGRESS',
                        source=BENCH_SOURCE,
                    )
                    for task_id in ids
                ]
            )
            publisher.publish(message)
            samples.append((time.perf_counter() - started) * 1e3)
    finally:
        node.destroy_publisher(publisher)
    return Summary.of(samples), len(serialize_message(message))


@dataclass(frozen=True)
class Usage:
    """The node's thread count and RSS."""

    threads: int
    rss_bytes: int


def resource_rows(count: int, idle: Usage, peak: Usage, waiting_cpu: CpuUse) -> list[Row]:
    growth = peak.threads - idle.threads
    return [
        Row(
            benchmark=f'concurrency {count}',
            metric=f'node CPU while all wait on their server, % of one core over '
            f'{config.WAITING_CPU_SEC:.0f} s',
            measured=f'{waiting_cpu.percent:.2f} %',
            baseline=wake_up_context(waiting_cpu),
            target=f'< {WAITING_CPU_TARGET_PERCENT:.0f} % (no per-task polling)',
            met=waiting_cpu.percent < WAITING_CPU_TARGET_PERCENT,
        ),
        Row(
            benchmark=f'concurrency {count}',
            metric='node threads, idle -> peak',
            measured=f'{idle.threads} -> {peak.threads}',
            baseline='',
            target='not growing',
            met=growth <= THREAD_GROWTH_ALLOWED,
        ),
        Row(
            benchmark=f'concurrency {count}',
            metric='node RSS MiB, idle -> peak',
            measured=f'{idle.rss_bytes / MIB:.0f} -> {peak.rss_bytes / MIB:.0f}',
            baseline='',
        ),
    ]


def hold_rows(count: int, direct: HoldRun, managed: HoldRun) -> list[Row]:
    def row(
        metric: str, measured_sec: float, baseline_sec: float, what: str, target: float | None
    ) -> Row:
        factor = ratio(measured_sec, baseline_sec)
        return Row(
            benchmark=f'concurrency {count}',
            metric=metric,
            measured=f'{measured_sec * 1e3:.0f}',
            baseline=f'{baseline_sec * 1e3:.0f} {what}',
            ratio=f'{factor:.1f}x',
            target=f'<= {target:.0f}x' if target else '',
            met=factor <= target if target else None,
        )

    return [
        row(
            'ms until all IN_PROGRESS',
            managed.ramp_sec,
            direct.ramp_sec,
            'direct accepted',
            RAMP_TARGET,
        ),
        row('ms from release to all results', managed.drain_sec, direct.drain_sec, 'direct', None),
    ]


def publication_rows(
    count: int, idle: Loaded, loaded: Loaded, copy: tuple[Summary, int]
) -> list[Row]:
    def row(
        metric: str, measured: Summary, baseline: Summary, what: str, target: float | None = None
    ) -> Row:
        factor = ratio(measured.median, baseline.median)
        return Row(
            benchmark=f'active_tasks at {count}',
            metric=metric,
            measured=measured.text(),
            baseline=f'{baseline.text()} {what}',
            ratio=f'{factor:.1f}x',
            target=f'<= {target:.0f}x' if target else '',
            met=factor <= target if target else None,
        )

    if not idle.publication_ms or not loaded.publication_ms:
        raise BenchError('the last two publications of no instant task were seen')
    return [
        row(
            f'instant task round trip ms with {count} active, med / p95',
            Summary.of(loaded.round_trip_ms),
            Summary.of(idle.round_trip_ms),
            'idle',
            LOADED_ROUND_TRIP_TARGET,
        ),
        row(
            'one publication in the node, ms (DDS stamps), med / p95',
            Summary.of(loaded.publication_ms),
            Summary.of(idle.publication_ms),
            'of 1 task',
        ),
        Row(
            benchmark=f'active_tasks at {count}',
            metric=f'build + publish one ({copy[1] / 1024:.0f} KiB) in the bench, ms, med / p95',
            measured=copy[0].text(),
            baseline='',
        ),
    ]


def idle_tasks(ctx: BenchContext, watcher: ActiveTasksWatcher) -> Loaded:
    """Instant tasks one after another with nothing else active: the baseline."""
    return instant_tasks(ctx, watcher, 0)


def run(ctx: BenchContext) -> None:
    count = config.CONCURRENT_TASKS
    direct = direct_hold(ctx, count)
    watcher = ActiveTasksWatcher(ctx.client.harness)
    sampler = ResourceSampler(ctx.node.pid)
    try:
        watcher.wait_until(bool, config.CONNECT_TIMEOUT_SEC, 'the current list')
        idle = idle_tasks(ctx, watcher)
        idle_usage = Usage(*sampler.sample())
        sampler.start()
        try:
            managed, loaded = managed_hold(ctx, watcher, count)
        finally:
            sampler.stop()
    finally:
        watcher.destroy()
    peak_usage = Usage(sampler.peak_threads, sampler.peak_rss_bytes)
    ctx.report.add(
        *hold_rows(count, direct, managed),
        *resource_rows(count, idle_usage, peak_usage, managed.waiting_cpu or CpuUse(0.0, 0.0)),
        *publication_rows(count, idle, loaded, publication_copy(ctx, count)),
    )
