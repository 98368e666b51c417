"""Feedback at 100 Hz: an instant task's round trip while another task's server publishes
feedback at 100 Hz, vs without (and the same goal sent directly, both ways).

The node (event stream on, its default) turns each feedback message into JSON, keeps it as
the task's latest and sends at most `feedback_rate_hz` (10) FEEDBACK events a second. Quiet
and busy blocks of samples alternate ABBA, each busy block with a feedback task of its own,
so that drift (the node's ExecuteTask server keeps each finished goal 10 s) hits both alike.
A busy block starts once the node has sent the task's first FEEDBACK event, and the bench
checks that the task was still running after the block's last sample.
"""

import json
import statistics
from dataclasses import dataclass
from typing import Any

from rclpy.task import Future

from bench.harness import config
from bench.harness.client import TaskEventsWatcher
from bench.harness.context import BenchContext, expect_done
from bench.harness.replies import BenchError, wait_reply
from bench.harness.report import Row
from bench.harness.stats import Summary, ratio
from bench.node.dispatch import interleaved

TARGET = 1.10
FIRST_FEEDBACK_TIMEOUT_SEC = 5.0


@dataclass
class FeedbackTotals:
    """What the feedback tasks of the busy blocks published, and what the node forwarded."""

    server_messages: int = 0
    server_sec: float = 0.0
    feedback_events: int = 0


# (through the manager, direct): round trips of the same instant goal, interleaved
Samples = tuple[list[float], list[float]]


def _samples(ctx: BenchContext) -> Samples:
    """Interleaved with the direct round trip, which tells the servers' share of a slowdown."""
    samples = config.FEEDBACK_BLOCK_SAMPLES
    return interleaved(ctx.fibonacci_task_ms, ctx.fibonacci_direct_ms, samples)


def busy_block(
    ctx: BenchContext, watcher: TaskEventsWatcher, task_id: str, totals: FeedbackTotals
) -> Samples:
    """Samples while the task `task_id` gets feedback at 100 Hz from its server."""
    replied: Future[Any] = ctx.accepted_task(config.FEEDBACK_TASK, config.FIBONACCI_DATA, task_id)
    watcher.wait_event('FEEDBACK', task_id, FIRST_FEEDBACK_TIMEOUT_SEC)
    samples = _samples(ctx)
    if replied.done():
        raise BenchError(f'{task_id} ended before the samples did: they measured nothing')
    released = wait_reply(ctx.client.call_trigger(ctx.client.release_feedback), 'release')
    published = json.loads(released.response.message)
    totals.server_messages += published['feedback_messages']
    totals.server_sec += published['seconds']
    expect_done(wait_reply(replied, task_id))
    events = watcher.take()
    totals.feedback_events += sum((e.event, e.task_id) == ('FEEDBACK', task_id) for e in events)
    return samples


def feedback_note(totals: FeedbackTotals) -> str:
    seconds = totals.server_sec or 1.0
    return (
        f'feedback: the servers published {totals.server_messages} feedback messages in '
        f'{totals.server_sec:.1f} s ({totals.server_messages / seconds:.0f} Hz); the node '
        f'sent {totals.feedback_events} FEEDBACK events for them '
        f'({totals.feedback_events / seconds:.1f} Hz)'
    )


def direct_note(quiet: list[float], busy: list[float]) -> str:
    quiet_ms, busy_ms = statistics.median(quiet), statistics.median(busy)
    return (
        f'feedback: the same goal sent directly, med {busy_ms:.2f} ms during the feedback vs '
        f'{quiet_ms:.2f} ms without ({ratio(busy_ms, quiet_ms):.2f}x)'
    )


def run(ctx: BenchContext) -> None:
    watcher = TaskEventsWatcher(ctx.client.harness)
    quiet: list[float] = []
    busy: list[float] = []
    quiet_direct: list[float] = []
    busy_direct: list[float] = []
    totals = FeedbackTotals()
    try:
        for round_index in range(config.FEEDBACK_ROUNDS):
            busy_first = round_index % 2 == 1
            for is_busy in (busy_first, not busy_first):
                if is_busy:
                    task_id = f'feedback-{round_index}'
                    manager, direct = busy_block(ctx, watcher, task_id, totals)
                    busy += manager
                    busy_direct += direct
                else:
                    manager, direct = _samples(ctx)
                    quiet += manager
                    quiet_direct += direct
        if ctx.profiling:
            with ctx.profiled('instant tasks while a server publishes feedback at 100 Hz'):
                busy_block(ctx, watcher, 'feedback-profiled', FeedbackTotals())
    finally:
        watcher.destroy()
    quiet_ms, busy_ms = Summary.of(quiet), Summary.of(busy)
    factor = ratio(busy_ms.median, quiet_ms.median)
    ctx.report.add(
        Row(
            benchmark='feedback 100 Hz',
            metric=f'instant task round trip ms, med / p95, n={busy_ms.count}',
            measured=busy_ms.text(),
            baseline=f'{quiet_ms.text()} no feedback',
            ratio=f'{factor:.2f}x',
            target=f'<= {TARGET:.2f}x',
            met=factor <= TARGET,
        )
    )
    ctx.report.note(feedback_note(totals))
    ctx.report.note(direct_note(quiet_direct, busy_direct))
