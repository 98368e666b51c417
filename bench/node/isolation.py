"""Isolation: start latency of an instant task while another task is stuck.

(a) a task waits for its missing action server (server_wait_timeout), (b) a task pre-empts a
service task that cannot be cancelled (cancel_timeout). Start latency is the round trip of an
instant task, which is all start: its server ends it in its first callback. The normal
samples are taken half before and half after each disturbance, so drift hits both alike.
"""

from typing import Any

from rclpy.task import Future

from bench.harness import config
from bench.harness.client import ActiveTasksWatcher, error_code, task_status
from bench.harness.context import BenchContext
from bench.harness.replies import BenchError, Reply, wait_reply
from bench.harness.report import Row
from bench.harness.stats import Summary, ratio

TARGET = 1.5
STATE_TIMEOUT_SEC = 10.0


def _start_latencies(ctx: BenchContext, samples: int) -> list[float]:
    return [ctx.fibonacci_task_ms() for _ in range(samples)]


def _normal(ctx: BenchContext) -> list[float]:
    """Half of the normal samples, taken before and again after each disturbance."""
    return _start_latencies(ctx, config.ISOLATION_SAMPLES // 2)


def _during(ctx: BenchContext, disturbance: Future[Any], what: str) -> list[float]:
    samples = _start_latencies(ctx, config.ISOLATION_SAMPLES)
    if disturbance.done():
        raise BenchError(f'{what} ended before the samples did: they measured nothing')
    return samples


def _expect(reply: Reply, status: str, code: str, what: str) -> None:
    if (task_status(reply), error_code(reply)) != (status, code):
        raise BenchError(f'{what} ended {task_status(reply)!r} {error_code(reply)!r}')


def _accepted(ctx: BenchContext, task_name: str, task_data: str, task_id: str) -> Future[Any]:
    """Send a task; return its reply future once the manager has accepted its goal."""
    accepted: Future[Any] = Future()
    replied = ctx.client.send_task(task_name, task_data, task_id, accepted)
    wait_reply(accepted, f'{task_id} accepted')
    return replied


def missing_server(ctx: BenchContext) -> tuple[list[float], list[float]]:
    normal = _normal(ctx)
    waiting = _accepted(ctx, config.MISSING_TASK, config.FIBONACCI_DATA, 'isolation-missing')
    disturbed = _during(ctx, waiting, 'the wait for the missing server')
    end = wait_reply(waiting, 'missing server task', config.SERVER_WAIT_TIMEOUT_SEC + 10)
    _expect(end, 'ERROR', 'task_start_failed', 'the task of the missing server')
    return normal + _normal(ctx), disturbed


def uncancellable_service(
    ctx: BenchContext, watcher: ActiveTasksWatcher
) -> tuple[list[float], list[float]]:
    normal = _normal(ctx)
    first_id = 'isolation-slow-1'
    first = ctx.client.send_task(config.SLOW_SERVICE_TASK, config.TRIGGER_DATA, first_id)
    watcher.wait_task_in_progress(first_id, STATE_TIMEOUT_SEC)
    second = _accepted(ctx, config.SLOW_SERVICE_TASK, config.TRIGGER_DATA, 'isolation-slow-2')
    disturbed = _during(ctx, second, 'the pre-emption of the service task')
    end = wait_reply(second, 'pre-empting task', config.SLOW_CANCEL_TIMEOUT_SEC + 10)
    _expect(end, 'ERROR', 'task_start_failed', 'the pre-empting task')
    ctx.client.release(ctx.client.release_calls, 'release of the held service call')
    _expect(wait_reply(first, 'held service task'), 'DONE', '', 'the held service task')
    return normal + _normal(ctx), disturbed


def _row(case: str, normal: list[float], disturbed: list[float]) -> Row:
    normal_ms, disturbed_ms = Summary.of(normal), Summary.of(disturbed)
    factor = ratio(disturbed_ms.median, normal_ms.median)
    return Row(
        benchmark=f'isolation {case}',
        metric=f'start latency ms, med / p95, n={disturbed_ms.count}',
        measured=disturbed_ms.text(),
        baseline=f'{normal_ms.text()} normal',
        ratio=f'{factor:.2f}x',
        target=f'<= {TARGET}x',
        met=factor <= TARGET,
    )


def run(ctx: BenchContext) -> None:
    watcher = ActiveTasksWatcher(ctx.client.harness)
    try:
        ctx.report.add(_row('(a) missing server', *missing_server(ctx)))
        ctx.report.add(_row('(b) uncancellable', *uncancellable_service(ctx, watcher)))
    finally:
        watcher.destroy()
