"""An executor that resumes a waiting coroutine only once the future it awaits has completed.

rclpy's executors resume every pending coroutine task at each wake-up (a timer, a message,
anything): with 1,000 tasks waiting on their servers, every wake-up steps 1,000 coroutines
that only find their future still pending. Here a task suspended on a pending rclpy Future
is *parked*: taken out of the executor's task list until that future completes, when it is
put back and the executor woken. A task suspended on anything else is resumed at each
wake-up, as before.

A task put back (or created) is also queued to run at the end of the executor's turn, before
it builds its wait set again: rclpy runs tasks created or woken during a turn only after
another wait, so each link of a chain (a response completes a future, whose callbacks complete
another, whose waiter answers) cost a rebuild of the wait set in Python. Here a turn goes on
with them, at most RUN_AHEAD_LIMIT, so that tasks waking each other never starve ready entities;
the entities found ready by one wait are still all handled before any of them.

Coroutine tasks made with `create_task` and the handlers rclpy makes for ready entities (an
async service callback) both park.

How the awaited future is known: `Future.__await__` is replaced (in this process, by
`install()`) by one that notes the future on a thread-local just before it yields; the task
reads the note after each step. Nothing else about futures changes.
"""

import threading
from collections import deque
from collections.abc import Callable, Generator
from typing import Any, cast

from rclpy.executors import SingleThreadedExecutor
from rclpy.task import Future, Task

_noted = threading.local()
# tasks run from the ready queue before the executor looks at its wait set again
RUN_AHEAD_LIMIT = 100


def _await_noting_the_future(self: Future[Any]) -> Generator[None, None, Any]:
    while self._pending():
        _noted.future = self
        yield
    return self.result()


def install() -> None:
    """Let coroutines awaiting rclpy futures tell the ParkingExecutor what they await."""
    Future.__await__ = _await_noting_the_future  # type: ignore[method-assign]


class _ParkingTask(Task[Any]):
    def __init__(self, executor: 'ParkingExecutor', handler: Callable[..., Any], args: Any,
                 kwargs: Any) -> None:  # fmt: skip
        super().__init__(handler, args, kwargs, executor=executor)
        self._parking = executor
        self.parked = False

    @classmethod
    def adopt(cls, task: Task[Any], executor: 'ParkingExecutor') -> '_ParkingTask':
        """Make a Task that rclpy created a parking one (same object, same state)."""
        task.__class__ = cls
        adopted = cast(_ParkingTask, task)
        adopted._parking = executor
        adopted.parked = False
        return adopted

    def __call__(self) -> None:
        _noted.future = None
        super().__call__()
        awaited, _noted.future = getattr(_noted, 'future', None), None
        if awaited is not None and self._pending() and not awaited.done():
            self._parking.park(self, awaited)


class ParkingExecutor(SingleThreadedExecutor):
    """A SingleThreadedExecutor whose coroutine tasks wait off its list (see the module)."""

    @property
    def resumes_waiters(self) -> bool:
        """Whether a coroutine awaiting a future is resumed when it completes (once `install()`
        has run): then rclpy_tools.futures.resolved queues no wake-up task for it."""
        return Future.__await__ is _await_noting_the_future

    def __init__(self) -> None:
        super().__init__()
        self._ready: deque[Task[Any]] = deque()

    def _wait_for_ready_callbacks(self, *args: Any, **kwargs: Any) -> Any:
        """rclpy's turn (the tasks in progress, a wait, the entities found ready), then the tasks
        that turn woke or created and those they woke in turn, at most RUN_AHEAD_LIMIT, before
        the next wait."""
        yield from super()._wait_for_ready_callbacks(*args, **kwargs)
        for _ in range(RUN_AHEAD_LIMIT):
            task = self._next_ready()
            if task is None:
                return
            yield task, None, None

    def _next_ready(self) -> Task[Any] | None:
        while self._ready and not self._is_shutdown:
            task = self._ready.popleft()
            if not (task.done() or task.executing() or getattr(task, 'parked', False)):
                return task
        return None

    def create_task(self, callback: Callable[..., Any], *args: Any, **kwargs: Any) -> Task[Any]:
        task = _ParkingTask(self, callback, args, kwargs)
        self._resume(task)
        return task

    def _make_handler(self, *args: Any, **kwargs: Any) -> Task[None]:
        """rclpy's handler of a ready entity (a service request, a message), made to park too:
        an async callback awaiting a future (ExecuteTask's get_result answers, one per task in
        flight) then waits off the list like any coroutine here."""
        return _ParkingTask.adopt(super()._make_handler(*args, **kwargs), self)

    def park(self, task: _ParkingTask, awaited: Future[Any]) -> None:
        """Take `task` off the list until `awaited` completes (or is cancelled)."""
        with self._tasks_lock:
            task.parked = True
            self._tasks = [entry for entry in self._tasks if entry[0] is not task]
        awaited.add_done_callback(lambda _: self._unpark(task))

    def _unpark(self, task: _ParkingTask) -> None:
        with self._tasks_lock:
            if not task.parked:
                return
            task.parked = False
        self._resume(task)

    def _resume(self, task: Task[Any]) -> None:
        """Put `task` on the list and wake the executor (thread-safe)."""
        with self._tasks_lock:
            self._tasks.append((task, None, None))
            self._ready.append(task)
            if self._guard:
                self._guard.trigger()
