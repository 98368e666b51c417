"""Dispatch latency: one instant task through the manager vs the same request sent directly."""

import statistics
from collections.abc import Callable

from bench.harness import config
from bench.harness.context import BenchContext
from bench.harness.report import Row
from bench.harness.stats import Summary, ratio

ACTION_TARGET = 2.3
SERVICE_TARGET = 3.0  # issue 16: one hop each way is the floor of both
DRIFT_EDGE_SAMPLES = 50
# after the measured samples: where a single task's time goes in the node
PROFILED_TASKS = 300


def interleaved(
    manager: Callable[[], float], direct: Callable[[], float], samples: int
) -> tuple[list[float], list[float]]:
    """Alternate which path goes first, so drift in the machine's load hits both alike."""
    manager_ms: list[float] = []
    direct_ms: list[float] = []
    for index in range(samples):
        if index % 2 == 0:
            manager_ms.append(manager())
            direct_ms.append(direct())
        else:
            direct_ms.append(direct())
            manager_ms.append(manager())
    return manager_ms, direct_ms


def _row(kind: str, manager_ms: list[float], direct_ms: list[float], target: float | None) -> Row:
    manager, direct = Summary.of(manager_ms), Summary.of(direct_ms)
    factor = ratio(manager.median, direct.median)
    return Row(
        benchmark=f'dispatch {kind}',
        metric=f'round trip ms, med / p95, n={manager.count}',
        measured=manager.text(),
        baseline=f'{direct.text()} direct',
        ratio=f'{factor:.2f}x',
        target=f'<= {target}x' if target else '',
        met=factor <= target if target else None,
    )


def run(ctx: BenchContext) -> None:
    interleaved(ctx.fibonacci_task_ms, ctx.fibonacci_direct_ms, config.WARM_UP_SAMPLES)
    interleaved(ctx.trigger_task_ms, ctx.trigger_direct_ms, config.WARM_UP_SAMPLES)
    ctx.settle()
    action = interleaved(ctx.fibonacci_task_ms, ctx.fibonacci_direct_ms, config.DISPATCH_SAMPLES)
    ctx.settle()
    service = interleaved(ctx.trigger_task_ms, ctx.trigger_direct_ms, config.DISPATCH_SAMPLES)
    ctx.report.add(
        _row('action', *action, ACTION_TARGET), _row('service', *service, SERVICE_TARGET)
    )
    ctx.report.note(drift_note(action[0]))
    if ctx.profiling:
        with ctx.profiled(f'dispatch: {PROFILED_TASKS} more instant action tasks, one by one'):
            for _ in range(PROFILED_TASKS):
                ctx.fibonacci_task_ms()


def drift_note(manager_ms: list[float]) -> str:
    """How the manager's latency moved within the run: its ExecuteTask server keeps goals 10 s."""
    edge = DRIFT_EDGE_SAMPLES
    first, last = statistics.median(manager_ms[:edge]), statistics.median(manager_ms[-edge:])
    return (
        f'dispatch action via the manager: median of the first {edge} samples {first:.2f} ms, '
        f'of the last {edge} {last:.2f} ms'
    )
