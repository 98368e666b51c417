"""The executors' take of a timer (WakelessExecutor._take_timer): rclpy's behaviour, what the
callback takes looked up once per callback instead of at every call."""

import inspect
from typing import Any

import pytest
from rclpy.node import Node
from rclpy.task import Future
from rclpy.timer import Timer, TimerInfo

from task_manager.rclpy_tools.wakeless_executor import WakelessExecutor
from task_manager.ros.parking_executor import ParkingExecutor

pytestmark = [
    pytest.mark.ros,
    pytest.mark.parametrize('spun', [WakelessExecutor, ParkingExecutor], indirect=True),
]
TIMEOUT_SEC = 5.0
PERIOD_SEC = 0.005
CALLS = 5


class SignatureCounted:
    """A timer callback that counts how often its signature is looked up."""

    def __init__(self, done: Future[None]) -> None:
        self.lookups = 0
        self.calls = 0
        self._done = done

    @property
    def __signature__(self) -> inspect.Signature:
        self.lookups += 1
        return inspect.Signature()

    def __call__(self) -> None:
        self.calls += 1
        if self.calls == CALLS:
            self._done.set_result(None)


def spin_until(executor: WakelessExecutor, done: Future[Any]) -> None:
    executor.spin_until_future_complete(done, timeout_sec=TIMEOUT_SEC)
    assert done.done()


def test_a_timers_callback_signature_is_looked_up_once(
    spun: tuple[WakelessExecutor, Node],
) -> None:
    executor, node = spun
    done: Future[None] = Future()
    callback = SignatureCounted(done)
    node.create_timer(PERIOD_SEC, callback)

    spin_until(executor, done)

    assert callback.calls == CALLS and callback.lookups == 1


def test_a_callback_taking_timer_info_gets_it_for_each_call(
    spun: tuple[WakelessExecutor, Node],
) -> None:
    executor, node = spun
    done: Future[None] = Future()
    infos: list[TimerInfo] = []

    def on_timer(info: TimerInfo) -> None:
        infos.append(info)
        if len(infos) == CALLS:
            done.set_result(None)

    node.create_timer(PERIOD_SEC, on_timer)
    spin_until(executor, done)

    expected = [info.expected_call_time.nanoseconds for info in infos]
    assert expected == sorted(set(expected))  # one per call, each later than the last


def test_a_coroutine_callback_is_awaited(spun: tuple[WakelessExecutor, Node]) -> None:
    executor, node = spun
    step: Future[None] = Future()
    done: Future[str] = Future()
    timer: Timer | None = None

    async def on_timer() -> None:
        assert timer is not None
        timer.cancel()
        if not step.done():
            step.set_result(None)
            await step
            done.set_result('went on after its await')

    timer = node.create_timer(PERIOD_SEC, on_timer)  # type: ignore[arg-type]  # rclpy runs coroutines
    spin_until(executor, done)

    assert done.result() == 'went on after its await'


def test_a_callback_replaced_at_run_time_is_looked_up_again(
    spun: tuple[WakelessExecutor, Node],
) -> None:
    """rclpy allows a timer's callback to change while it runs."""
    executor, node = spun
    first_done: Future[None] = Future()
    second_done: Future[None] = Future()
    first, second = SignatureCounted(first_done), SignatureCounted(second_done)
    timer = node.create_timer(PERIOD_SEC, first)
    spin_until(executor, first_done)

    timer.callback = second
    spin_until(executor, second_done)

    assert (first.lookups, second.lookups) == (1, 1)
    assert second.calls == CALLS
