"""Throughput: a burst of instant reentrant tasks from one client, vs the same burst direct."""

import statistics

from test_msgs.action import Fibonacci

from bench.harness import config
from bench.harness.client import execute_task_goal, task_status
from bench.harness.context import BenchContext, succeeded
from bench.harness.replies import BenchError
from bench.harness.report import Row
from bench.harness.stats import burst, ratio

TARGET_SHARE = 0.50


def manager_burst(ctx: BenchContext, count: int, round_index: int) -> float:
    """Tasks per second of `count` instant tasks sent at once through the manager."""
    goal = execute_task_goal(config.FIBONACCI_TASK, config.FIBONACCI_DATA)
    seconds, replies = burst(
        lambda _: ctx.client.execute_task.send_goal(goal),
        count,
        f'manager burst {round_index}',
    )
    failed = sum(1 for reply in replies if task_status(reply) != 'DONE')
    if failed:
        raise BenchError(f'manager burst {round_index}: {failed} of {count} tasks not DONE')
    return count / seconds


def direct_burst(ctx: BenchContext, count: int, round_index: int) -> float:
    """Goals per second of `count` instant goals sent at once to the server itself."""
    goal = Fibonacci.Goal(order=0)
    seconds, replies = burst(
        lambda _: ctx.client.fibonacci.send_goal(goal),
        count,
        f'direct burst {round_index}',
    )
    failed = sum(1 for reply in replies if not succeeded(reply))
    if failed:
        raise BenchError(f'direct burst {round_index}: {failed} of {count} goals failed')
    return count / seconds


def _spread(rates: list[float]) -> str:
    return f'{statistics.median(rates):.0f} ({min(rates):.0f}-{max(rates):.0f})'


def run(ctx: BenchContext) -> None:
    manager_rates: list[float] = []
    direct_rates: list[float] = []
    count = config.THROUGHPUT_TASKS
    for index in range(config.THROUGHPUT_ROUNDS):
        if index > 0:
            ctx.settle()
        # alternate the order, so that drift in the machine's load hits both alike
        if index % 2 == 0:
            manager_rates.append(manager_burst(ctx, count, index))
            direct_rates.append(direct_burst(ctx, count, index))
        else:
            direct_rates.append(direct_burst(ctx, count, index))
            manager_rates.append(manager_burst(ctx, count, index))
    share = ratio(statistics.median(manager_rates), statistics.median(direct_rates))
    ctx.report.add(
        Row(
            benchmark='throughput action',
            metric=f'tasks/s, {count} at once, med (min-max) of {len(manager_rates)}',
            measured=_spread(manager_rates),
            baseline=f'{_spread(direct_rates)} direct',
            ratio=f'{share:.0%}',
            target=f'>= {TARGET_SHARE:.0%}',
            met=share >= TARGET_SHARE,
        )
    )
    if ctx.profiling:
        ctx.settle()
        with ctx.profiled(f'throughput: an extra burst of {count} instant tasks'):
            manager_burst(ctx, count, config.THROUGHPUT_ROUNDS)
