"""Throughput: a burst of instant reentrant tasks from one client, vs the same burst direct.

And the floor: the same burst through the least relay of the same protocol in rclpy
(bench/harness/relay.py), in a process of its own, rounds rotated with the other two paths.
"""

import contextlib
import statistics
from collections.abc import Iterator

from test_msgs.action import Fibonacci

from bench.harness import config
from bench.harness.client import execute_task_goal, task_status
from bench.harness.context import BenchContext, succeeded
from bench.harness.lean_action import LeanActionClient
from bench.harness.processes import start_relay
from bench.harness.replies import BenchError
from bench.harness.report import Row
from bench.harness.stats import burst, ratio
from task_manager_msgs.action import ExecuteTask

TARGET_SHARE = 0.50


def manager_burst(ctx: BenchContext, count: int, round_index: int) -> float:
    """Tasks per second of `count` instant tasks sent at once through the manager."""
    return execute_task_burst(ctx.client.execute_task, count, f'manager burst {round_index}')


def execute_task_burst(server: LeanActionClient, count: int, what: str) -> float:
    """Tasks per second of `count` instant tasks sent at once to an ExecuteTask server (the
    manager's, or the floor relay's); each must end DONE."""
    goal = execute_task_goal(config.FIBONACCI_TASK, config.FIBONACCI_DATA)
    seconds, replies = burst(lambda _: server.send_goal(goal), count, what)
    failed = sum(1 for reply in replies if task_status(reply) != 'DONE')
    if failed:
        raise BenchError(f'{what}: {failed} of {count} tasks not DONE')
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


@contextlib.contextmanager
def floor_relay(ctx: BenchContext) -> Iterator[LeanActionClient]:
    """The relay's process, and the bench's client of its ExecuteTask, while the body runs."""
    process = start_relay(ctx.log_dir)
    client = LeanActionClient(ctx.client.harness.node, ExecuteTask, config.RELAY_ACTION)
    try:
        if not client.wait_for_server(config.CONNECT_TIMEOUT_SEC):
            raise BenchError(
                f'the floor relay did not serve within {config.CONNECT_TIMEOUT_SEC} s'
                f'\n--- relay log ---\n{process.log_tail()}'
            )
        execute_task_burst(client, config.WARM_UP_SAMPLES, 'relay warm-up')
        yield client
    finally:
        client.destroy()
        process.stop()


def _spread(rates: list[float]) -> str:
    return f'{statistics.median(rates):.0f} ({min(rates):.0f}-{max(rates):.0f})'


def run(ctx: BenchContext) -> None:
    count = config.THROUGHPUT_TASKS
    rates: dict[str, list[float]] = {'manager': [], 'direct': [], 'relay': []}
    with floor_relay(ctx) as relay:
        paths = {
            'manager': lambda index: manager_burst(ctx, count, index),
            'direct': lambda index: direct_burst(ctx, count, index),
            'relay': lambda index: execute_task_burst(relay, count, f'relay burst {index}'),
        }
        order = list(paths)
        for index in range(config.THROUGHPUT_ROUNDS):
            if index > 0:
                ctx.settle()
            # rotate the order, so that drift in the machine's load hits every path alike
            for name in order[index % 3 :] + order[: index % 3]:
                rates[name].append(paths[name](index))
    manager, direct, relay_rate = (statistics.median(rates[name]) for name in paths)
    share = ratio(manager, direct)
    ctx.report.add(
        Row(
            benchmark='throughput action',
            metric=f'tasks/s, {count} at once, med (min-max) of {len(rates["manager"])}',
            measured=_spread(rates['manager']),
            baseline=f'{_spread(rates["direct"])} direct',
            ratio=f'{share:.0%}',
            target=f'>= {TARGET_SHARE:.0%}',
            met=share >= TARGET_SHARE,
        )
    )
    ctx.report.add(
        Row(
            benchmark='throughput action, floor',
            metric=f'tasks/s, {count} at once, vs the least relay in rclpy (relay.py), med',
            measured=f'{manager:.0f}',
            baseline=f'{_spread(rates["relay"])} relay ({ratio(relay_rate, direct):.0%} of direct)',
            ratio=f'{ratio(manager, relay_rate):.0%}',
        )
    )
    if ctx.profiling:
        ctx.settle()
        with ctx.profiled(f'throughput: an extra burst of {count} instant tasks'):
            manager_burst(ctx, count, config.THROUGHPUT_ROUNDS)
