"""Awaiting rclpy futures from coroutines, with bounds driven by the node's timer of timeouts
(rclpy_tools.timeouts): no thread, no polling.

rclpy's executors resume a waiting coroutine only when they next wake up. When one task
completes a future that another task awaits, nothing wakes the executor, and the waiting
task would sit until some unrelated event. `resolved` wakes it by queueing an empty task,
which every rclpy executor handles (guard conditions are not supported by all of them).
"""

from collections.abc import Callable, Sequence
from functools import partial
from typing import Any, TypeVar

from rclpy.node import Node
from rclpy.task import Future

from task_manager.rclpy_tools.cleanup import destroy_timer
from task_manager.rclpy_tools.timeouts import timeouts_of

T = TypeVar('T')


def _nothing() -> None:
    """An empty task: queueing it wakes the executor."""


def wake(node: Node) -> None:
    """Make the node's executor run its waiting coroutines (thread-safe)."""
    if node.executor is not None:
        node.executor.create_task(_nothing)


async def resolved(node: Node, future: Future[T]) -> T | None:
    """Await `future` and return its result (None if cancelled), waking the executor at once.

    An executor that resumes a coroutine itself when the future it awaits completes (its
    `resumes_waiters` is true: the node's ParkingExecutor) needs no wake-up task.
    """
    if not future.done():
        if not getattr(node.executor, 'resumes_waiters', False):
            future.add_done_callback(lambda _: wake(node))
        await future
    return future.result()


def result_of(future: Future[T]) -> T:
    """The result of a completed `future` whose result is never None.

    rclpy's `result()` also returns None for a pending or cancelled future; that is an error
    here (RuntimeError), not a value.
    """
    result = future.result()
    if result is None:
        if future.cancelled():
            raise RuntimeError('expected the result of a future that was cancelled')
        if not future.done():
            raise RuntimeError('expected the result of a future that is not done')
        raise RuntimeError('a future completed with None where a result was expected')
    return result


def completed_future(value: Any = None) -> Future[Any]:
    future: Future[Any] = Future()
    future.set_result(value)
    return future


def _complete_with(target: Future[T], value: T, _: Future[Any]) -> None:
    """A done callback: complete `target` with `value`, unless it is already done."""
    if not target.done():
        target.set_result(value)


def first_completed(futures: Sequence[Future[Any]]) -> Future[int]:
    """A future that completes with the index of the first of `futures` to complete."""
    first: Future[int] = Future()
    for index, future in enumerate(futures):
        if future.done():
            first.set_result(index)
            return first
    for index, future in enumerate(futures):
        future.add_done_callback(partial(_complete_with, first, index))
    return first


def all_completed(futures: Sequence[Future[Any]]) -> Future[None]:
    """A future that completes (with None) once every one of `futures` has completed."""
    everything: Future[None] = Future()
    pending = [f for f in futures if not f.done()]
    remaining = [len(pending)]
    if not pending:
        everything.set_result(None)
        return everything

    def on_done(_: Future[Any]) -> None:
        remaining[0] -= 1
        if remaining[0] == 0 and not everything.done():
            everything.set_result(None)

    for future in pending:
        future.add_done_callback(on_done)
    return everything


async def wait_for(node: Node, future: Future[Any], timeout_sec: float) -> bool:
    """Await `future` for at most `timeout_sec`; True if it completed in time."""
    if future.done():
        return True
    if timeout_sec <= 0:
        return False
    deadline: Future[None] = Future()
    timeouts = timeouts_of(node)
    key = timeouts.after(
        timeout_sec, lambda: None if deadline.done() else deadline.set_result(None)
    )
    try:
        winner = await resolved(node, first_completed([future, deadline]))
    finally:
        timeouts.cancel(key)
    return winner == 0 or future.done()


# rclpy offers no callback for graph changes, so server discovery is re-checked on a
# timer at this period, bounded by the caller's timeout (only while a server is missing).
READINESS_CHECK_PERIOD_SEC = 0.05


async def wait_until_ready(node: Node, is_ready: Callable[[], bool], timeout_sec: float) -> bool:
    """Await `is_ready()` becoming true for at most `timeout_sec`."""
    if is_ready():
        return True
    ready: Future[None] = Future()
    deadline: Future[None] = Future()

    def check() -> None:
        if not ready.done() and is_ready():
            ready.set_result(None)

    checker = node.create_timer(READINESS_CHECK_PERIOD_SEC, check)
    timeouts = timeouts_of(node)
    limit = timeouts.after(
        timeout_sec, lambda: None if deadline.done() else deadline.set_result(None)
    )
    try:
        await resolved(node, first_completed([ready, deadline]))
    finally:
        timeouts.cancel(limit)
        checker.cancel()
        destroy_timer(node, checker)
    return ready.done() or bool(is_ready())
