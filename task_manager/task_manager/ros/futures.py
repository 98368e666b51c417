"""Awaiting rclpy futures from coroutines, with bounds driven by timers: no thread, no polling.

rclpy's executors resume a waiting coroutine only when they next wake up. When one task
completes a future that another task awaits, nothing wakes the executor, and the waiting
task would sit until some unrelated event. `resolved` wakes it by queueing an empty task,
which every rclpy executor handles (guard conditions are not supported by all of them).
"""

from collections.abc import Sequence
from typing import Any

from rclpy.node import Node
from rclpy.task import Future


def _nothing() -> None:
    """An empty task: queueing it wakes the executor."""


def wake(node: Node) -> None:
    """Make the node's executor run its waiting coroutines (thread-safe)."""
    if node.executor is not None:
        node.executor.create_task(_nothing)


async def resolved(node: Node, future: Future) -> Any:
    """Await `future` and return its result; the executor is woken as soon as it completes."""
    if not future.done():
        future.add_done_callback(lambda _: wake(node))
        await future
    return future.result()


def completed_future(value: Any = None) -> Future:
    future: Future = Future()
    future.set_result(value)
    return future


def first_completed(futures: Sequence[Future]) -> Future:
    """A future that completes with the index of the first of `futures` to complete."""
    first: Future = Future()
    for index, future in enumerate(futures):
        if future.done():
            first.set_result(index)
            return first
    for index, future in enumerate(futures):
        future.add_done_callback(lambda _, i=index: None if first.done() else first.set_result(i))
    return first


def all_completed(futures: Sequence[Future]) -> Future:
    """A future that completes (with None) once every one of `futures` has completed."""
    everything: Future = Future()
    pending = [f for f in futures if not f.done()]
    remaining = [len(pending)]
    if not pending:
        everything.set_result(None)
        return everything

    def on_done(_: Future) -> None:
        remaining[0] -= 1
        if remaining[0] == 0 and not everything.done():
            everything.set_result(None)

    for future in pending:
        future.add_done_callback(on_done)
    return everything


async def wait_for(node: Node, future: Future, timeout_sec: float) -> bool:
    """Await `future` for at most `timeout_sec`; True if it completed in time."""
    if future.done():
        return True
    if timeout_sec <= 0:
        return False
    deadline: Future = Future()
    timer = node.create_timer(
        timeout_sec, lambda: None if deadline.done() else deadline.set_result(None)
    )
    try:
        winner = await resolved(node, first_completed([future, deadline]))
    finally:
        timer.cancel()
        node.destroy_timer(timer)
    return winner == 0 or future.done()


# rclpy offers no callback for graph changes, so server discovery is re-checked on a
# timer at this period, bounded by the caller's timeout (only while a server is missing).
READINESS_CHECK_PERIOD_SEC = 0.05


async def wait_until_ready(node: Node, is_ready: Any, timeout_sec: float) -> bool:
    """Await `is_ready()` becoming true for at most `timeout_sec`."""
    if is_ready():
        return True
    ready: Future = Future()
    deadline: Future = Future()

    def check() -> None:
        if not ready.done() and is_ready():
            ready.set_result(None)

    checker = node.create_timer(READINESS_CHECK_PERIOD_SEC, check)
    limit = node.create_timer(
        timeout_sec, lambda: None if deadline.done() else deadline.set_result(None)
    )
    try:
        await resolved(node, first_completed([ready, deadline]))
    finally:
        for timer in (checker, limit):
            timer.cancel()
            node.destroy_timer(timer)
    return ready.done() or bool(is_ready())
