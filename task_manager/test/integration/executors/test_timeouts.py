"""A node's timeouts on one timer: each action runs once its delay has passed, earliest first,
unless cancelled; however many are pending, the node has one timer for them."""

import time

import pytest
import rclpy
from rclpy.task import Future

from task_manager.rclpy_tools.futures import wait_for
from task_manager.rclpy_tools.timeouts import timeouts_of
from task_manager.rclpy_tools.wakeless_executor import WakelessExecutor
from task_manager.ros.running.deadline_timer import Deadline, DeadlineTimer

pytestmark = pytest.mark.ros
TIMEOUT_SEC = 5.0


def spin_until(executor: WakelessExecutor, future: Future[None]) -> None:
    executor.spin_until_future_complete(future, timeout_sec=TIMEOUT_SEC)
    assert future.done()


def test_actions_run_after_their_delays_earliest_first_on_one_timer(
    spun: tuple[WakelessExecutor, rclpy.node.Node],
) -> None:
    executor, node = spun
    timeouts = timeouts_of(node)
    ran: list[str] = []
    done: Future[None] = Future()
    started = time.monotonic()

    def late() -> None:
        ran.append('late')
        done.set_result(None)

    timeouts.after(0.2, late)
    timeouts.after(0.05, lambda: ran.append('early'))  # arms the timer earlier
    cancelled = timeouts.after(0.1, lambda: ran.append('cancelled'))
    timeouts.cancel(cancelled)
    assert len(list(node.timers)) == 1
    spin_until(executor, done)
    assert ran == ['early', 'late'] and time.monotonic() - started >= 0.2


def test_bounded_waits_make_no_timer_of_their_own(
    spun: tuple[WakelessExecutor, rclpy.node.Node],
) -> None:
    """futures.wait_for made and destroyed a timer per wait: a change of the node's timers,
    and so of the executor's wait set, twice per task."""
    executor, node = spun
    answered: Future[None] = Future()
    never: Future[None] = Future()
    results: list[bool] = []
    done: Future[None] = Future()

    async def waits() -> None:
        results.append(await wait_for(node, never, 0.05))
        answered.set_result(None)
        results.append(await wait_for(node, answered, 0.05))
        done.set_result(None)

    timeouts_of(node)  # its one timer, made once
    timers = list(node.timers)
    executor.create_task(waits)
    executor.spin_once(timeout_sec=0.0)  # up to the first wait's await
    timers_while_waiting = list(node.timers)
    spin_until(executor, done)
    assert results == [False, True] and timers_while_waiting == timers


def test_an_action_that_raises_loses_none_of_the_others(
    spun: tuple[WakelessExecutor, rclpy.node.Node],
) -> None:
    """A bug of ours raising in one action is raised to the executor's caller (the node logs
    it and goes on), after the actions due with it have run."""
    executor, node = spun
    timeouts = timeouts_of(node)
    done: Future[None] = Future()

    def raises() -> None:
        raise ValueError('a bug')

    timeouts.after(0.05, raises)
    timeouts.after(0.05, lambda: done.set_result(None))
    with pytest.raises(ValueError, match='a bug'):
        executor.spin_until_future_complete(done, timeout_sec=TIMEOUT_SEC)
    assert done.done()


def test_a_task_deadline_that_raises_loses_none_of_the_others(
    spun: tuple[WakelessExecutor, rclpy.node.Node],
) -> None:
    """The node's DeadlineTimer ran its due actions in a plain loop: one that raised lost the
    others due with it (a task's timeout never ending it)."""
    executor, node = spun
    deadlines = DeadlineTimer(node)
    done: Future[None] = Future()

    def raises() -> None:
        raise ValueError('a bug')

    deadlines.set('first', Deadline.RUN, 0.05, raises)
    deadlines.set('second', Deadline.RUN, 0.05, lambda: done.set_result(None))
    with pytest.raises(ValueError, match='a bug'):
        executor.spin_until_future_complete(done, timeout_sec=TIMEOUT_SEC)
    assert done.done()
