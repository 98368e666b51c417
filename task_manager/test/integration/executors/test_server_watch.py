"""The server watch's checks call only the tasks that asked for it (ServerWatch), on a real
node's timer: a thousand goals held for minutes cost no work per goal at each check."""

import pytest
from rclpy.node import Node
from rclpy.task import Future

from task_manager.rclpy_tools.wakeless_executor import WakelessExecutor
from task_manager.ros.running.server_watch import ServerWatch, WatchSettings

pytestmark = pytest.mark.ros
TIMEOUT_SEC = 5.0
CHECKS = 12
SETTINGS = WatchSettings(check_period_sec=0.01, loss_timeout_sec=60.0)


class Execution:
    """A task in flight that wants its next call `every` checks after each (None: never)."""

    def __init__(self, every: int | None) -> None:
        self.outcome: Future[None] = Future()
        self.every = every
        self.called_at: list[int] = []

    def fail(self, reason: str) -> None:
        self.outcome.set_result(None)

    def on_watch_tick(self, tick: int) -> int | None:
        self.called_at.append(tick)
        return None if self.every is None else tick + self.every


def watch_checks(
    spun: tuple[WakelessExecutor, Node],
    executions: list[Execution],
    every_one_at: frozenset[int] = frozenset(),
) -> None:
    """Track the executions and spin until the watch has made CHECKS checks; at the checks in
    `every_one_at` its on_tick asks for every execution to be called."""
    executor, node = spun
    checks: list[int] = []
    done: Future[None] = Future()

    def on_tick() -> bool:
        checks.append(len(checks) + 1)
        if len(checks) == CHECKS:
            done.set_result(None)
        return checks[-1] in every_one_at

    watch = ServerWatch(node, lambda: True, SETTINGS, loss='lost', on_tick=on_tick)
    for execution in executions:
        watch.track(execution)
    executor.spin_until_future_complete(done, timeout_sec=TIMEOUT_SEC)
    assert done.done()


def test_each_task_is_called_at_its_first_check_then_only_when_it_asked(
    spun: tuple[WakelessExecutor, Node],
) -> None:
    every_third = [Execution(3) for _ in range(50)]
    once = [Execution(None) for _ in range(50)]

    watch_checks(spun, every_third + once)

    assert all(e.called_at == [1, 4, 7, 10] for e in every_third)
    assert all(e.called_at == [1] for e in once)


def test_a_check_whose_on_tick_says_so_calls_every_task(
    spun: tuple[WakelessExecutor, Node],
) -> None:
    """As when an action server's DDS ids changed: each goal looks for a restart."""
    every_third, once = Execution(3), Execution(None)

    watch_checks(spun, [every_third, once], every_one_at=frozenset({5, 6}))

    assert every_third.called_at == [1, 4, 5, 6, 9, 12]  # each call asks for 3 checks later
    assert once.called_at == [1, 5, 6]


def test_a_task_that_ended_is_not_called_again(spun: tuple[WakelessExecutor, Node]) -> None:
    ending = Execution(1)

    def end_at_third(tick: int) -> int | None:
        ending.called_at.append(tick)
        if tick == 3:
            ending.outcome.set_result(None)
        return tick + 1

    ending.on_watch_tick = end_at_third  # type: ignore[method-assign]
    watch_checks(spun, [ending, Execution(None)], every_one_at=frozenset({8}))

    assert ending.called_at == [1, 2, 3]
