"""Dispatch latency: one instant task through the manager vs the same request sent directly,
and how far the manager is from the floor its own protocol sets.

The floor: ExecuteTask is itself an action, so a client's round trip through the manager is at
least that of a direct action call (send_goal answered, then get_result answered), and the task's
own calls to its server come between. With a node that costs nothing, and each one-way hop taking
as long as any other: an action task takes one and a half direct action round trips (the client's
goal is answered while the node sends the server its goal; the client's get_result waits for the
node's two exchanges with the server), a service task one (the node's call to the service runs
while the client's get_result is on its way). Measured beside the manager, in the same phase.
"""

import statistics
from collections.abc import Callable, Sequence

from bench.harness import config
from bench.harness.context import BenchContext
from bench.harness.report import Row
from bench.harness.stats import Summary, ratio

ACTION_TARGET = 2.3
SERVICE_TARGET = 3.0
# an action task's floor, in direct action round trips; a service task's is one
ACTION_FLOOR_ROUND_TRIPS = 1.5
DRIFT_EDGE_SAMPLES = 50
# after the measured samples: where a single task's time goes in the node
PROFILED_TASKS = 300


def interleaved(
    manager: Callable[[], float], direct: Callable[[], float], samples: int
) -> tuple[list[float], list[float]]:
    """Alternate which path goes first, so drift in the machine's load hits both alike."""
    manager_ms, direct_ms = rotated((manager, direct), samples)
    return manager_ms, direct_ms


def rotated(paths: Sequence[Callable[[], float]], samples: int) -> list[list[float]]:
    """Each path's samples, the order of the paths rotated at each sample (see interleaved)."""
    measured: list[list[float]] = [[] for _ in paths]
    for index in range(samples):
        for offset in range(len(paths)):
            which = (index + offset) % len(paths)
            measured[which].append(paths[which]())
    return measured


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


def _floor_row(kind: str, manager_ms: list[float], floor_ms: float, direct_ms: float) -> Row:
    manager = statistics.median(manager_ms)
    return Row(
        benchmark=f'dispatch {kind}, floor',
        metric='round trip ms vs the floor (module docstring), med',
        measured=f'{manager:.2f}',
        baseline=f'{floor_ms:.2f} floor ({ratio(floor_ms, direct_ms):.2f}x direct {kind})',
        ratio=f'{ratio(manager, floor_ms):.2f}x',
    )


def run(ctx: BenchContext) -> None:
    interleaved(ctx.fibonacci_task_ms, ctx.fibonacci_direct_ms, config.WARM_UP_SAMPLES)
    interleaved(ctx.trigger_task_ms, ctx.trigger_direct_ms, config.WARM_UP_SAMPLES)
    ctx.settle()
    action = interleaved(ctx.fibonacci_task_ms, ctx.fibonacci_direct_ms, config.DISPATCH_SAMPLES)
    ctx.settle()
    # the direct action round trip beside the service samples: the service task's floor
    service_ms, trigger_ms, fibonacci_ms = rotated(
        (ctx.trigger_task_ms, ctx.trigger_direct_ms, ctx.fibonacci_direct_ms),
        config.DISPATCH_SAMPLES,
    )
    action_direct = statistics.median(action[1])
    ctx.report.add(
        _row('action', *action, ACTION_TARGET),
        _floor_row('action', action[0], ACTION_FLOOR_ROUND_TRIPS * action_direct, action_direct),
        _row('service', service_ms, trigger_ms, SERVICE_TARGET),
        _floor_row(
            'service', service_ms, statistics.median(fibonacci_ms), statistics.median(trigger_ms)
        ),
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
