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

A service or a client that had a request (a response) taken in a turn is taken from again at
the end of that turn, within the same limit, until it has none: rclpy takes one message per
entity per wait, so a burst of 500 goals cost 500 wait sets on ExecuteTask's send_goal alone.
That next message is taken before a task is made for it: one with none left costs no task.

A response completes its request's future in its handler, whose done callbacks run there and
then (rclpy_tools.calls): rclpy gives the future its executor first, which runs each done
callback as a task of its own, and finds the request among all those pending.

What gathers the changes of a turn (a history commit, a list published whole) is queued with
`spawn_after_turn`: it runs once nothing else is ready, just before the executor waits again;
a turn that reaches RUN_AHEAD_LIMIT first hands it to the next turn as tasks in progress, which
run before that turn waits (never after an unrelated event).

Wake-ups are spared where they only cost a turn with nothing ready: the handlers of ready
entities do not wake it (rclpy_tools.wakeless_executor), and putting a task back or making an
entity (a timer of a bounded wait), which wakes rclpy's once, does not either in the
executor's thread after its wait has found work: what was queued runs at the turn's end
anyway, and the next wait set is built after it. From another thread, or before the wait,
the executor is woken as in rclpy. An instant service task costs about its three outside
events in turns.

Coroutine tasks made with `create_task` and the handlers made for ready entities (an async
service callback) both park.

How the awaited future is known: `Future.__await__` is replaced (in this process, by
`install()`) by one that notes the future on a thread-local just before it yields; the task
reads the note after each step. Nothing else about futures changes.
"""

import threading
from collections import deque
from collections.abc import Callable, Coroutine, Generator
from typing import Any

from rclpy.client import Client
from rclpy.exceptions import InvalidHandle
from rclpy.executors import TimeoutException, await_or_execute
from rclpy.node import Node
from rclpy.service import Service
from rclpy.task import Future, Task

from task_manager.rclpy_tools.calls import take_pending
from task_manager.rclpy_tools.wakeless_executor import Execute, Take, WakelessExecutor

_noted = threading.local()
# tasks run, and messages taken, at the end of a turn before the executor waits again
RUN_AHEAD_LIMIT = 100

_Handler = Callable[..., Any] | Coroutine[Any, Any, Any]


def _await_noting_the_future(self: Future[Any]) -> Generator[None, None, Any]:
    while self._pending():
        _noted.future = self
        yield
    return self.result()


def install() -> None:
    """Let coroutines awaiting rclpy futures tell the ParkingExecutor what they await."""
    Future.__await__ = _await_noting_the_future  # type: ignore[method-assign]


def spawn(node: Node, coroutine: Coroutine[Any, Any, Any]) -> None:
    """Run `coroutine` as a task of the node's executor."""
    executor = node.executor
    assert executor is not None, 'the node must be added to an executor'
    executor.create_task(coroutine)  # type: ignore[call-overload]


def spawn_after_turn(node: Node, coroutine: Coroutine[Any, Any, Any]) -> None:
    """Run `coroutine` once the node's executor has handled what is ready now: on a
    ParkingExecutor just before it waits again, on another executor as a task."""
    executor = node.executor
    assert executor is not None, 'the node must be added to an executor'
    if isinstance(executor, ParkingExecutor):
        executor.create_task_after_turn(coroutine)
    else:
        executor.create_task(coroutine)  # type: ignore[call-overload]


class _ParkingTask(Task[Any]):
    def __init__(self, executor: 'ParkingExecutor', handler: '_Handler', args: Any,
                 kwargs: Any) -> None:  # fmt: skip
        # rclpy runs a coroutine object too, but types its handler as a callable only
        super().__init__(handler, args, kwargs, executor=executor)  # type: ignore[arg-type]
        self._parking = executor
        self.parked = False

    def __call__(self) -> None:
        _noted.future = None
        super().__call__()
        awaited, _noted.future = getattr(_noted, 'future', None), None
        if awaited is not None and self._pending() and not awaited.done():
            self._parking.park(self, awaited)


class ParkingExecutor(WakelessExecutor):
    """A WakelessExecutor whose coroutine tasks wait off its list (see the module)."""

    @property
    def resumes_waiters(self) -> bool:
        """Whether a coroutine awaiting a future is resumed when it completes (once `install()`
        has run): then rclpy_tools.futures.resolved queues no wake-up task for it."""
        return Future.__await__ is _await_noting_the_future

    def __init__(self) -> None:
        super().__init__()
        self._ready: deque[Task[Any]] = deque()
        # services and clients a message was taken from this turn: maybe more are waiting
        self._taken: deque[tuple[Service[Any, Any] | Client[Any, Any], Node, Take]] = deque()
        self._after_turn: deque[Task[Any]] = deque()
        # whether this turn has waited and found work: what is queued meanwhile, in the
        # executor's thread, runs at the turn's end without a wake-up
        self._waited = False
        self._thread = 0

    def _wait_for_ready_callbacks(self, *args: Any, **kwargs: Any) -> Any:
        """rclpy's turn (the tasks in progress, a wait, the entities found ready), then the tasks
        that turn woke or created and those they woke in turn, and the next messages of the
        services and clients it took from, at most RUN_AHEAD_LIMIT, before the next wait."""
        self._waited = False
        self._thread = threading.get_ident()
        try:
            yield from super()._wait_for_ready_callbacks(*args, **kwargs)
        except TimeoutException:
            if not (self._ready or self._after_turn):
                raise  # nothing left of this turn: spin_once(timeout) returns
        self._waited = True
        limit_reached = True
        for _ in range(RUN_AHEAD_LIMIT):
            work = self._next_ready() or self._next_take() or self._next_after_turn()
            if work is None:
                limit_reached = False
                break
            yield work
        self._waited = False
        self._taken.clear()
        if limit_reached and (self._ready or self._after_turn):
            self._carry_over_after_turn()
            self._wake()  # the rest runs after the next wait, which must not block

    def _carry_over_after_turn(self) -> None:
        """What was to run at this turn's end goes on the task list, after the ready tasks:
        rclpy's next turn runs its tasks in progress before it waits, whereas a wait woken with
        nothing ready (only the guard) is waited again, until an unrelated event."""
        with self._tasks_lock:
            while self._after_turn:
                self._tasks.append((self._after_turn.popleft(), None, None))

    def create_task_after_turn(self, callback: _Handler) -> Task[Any]:
        """A task that runs once nothing else is ready, just before the executor waits again;
        queued outside a turn that has found work (before its wait, between spins, from another
        thread), it runs like any task: there is no turn's end to wait for."""
        task = _ParkingTask(self, callback, (), {})
        if self._in_waited_turn():
            self._after_turn.append(task)
        else:
            self._resume(task)
        return task

    def _in_waited_turn(self) -> bool:
        """In the executor's thread, in a turn whose wait has found work: what is queued now
        runs at the turn's end."""
        return self._waited and threading.get_ident() == self._thread

    def wake(self) -> None:
        """rclpy's wake-up (a node made or destroyed an entity, e.g. a timer), spared as in
        `_wake`: the next wait set is built after this turn and includes it."""
        self._wake()

    def _wake(self) -> None:
        """Make the next wait return at once, unless the end of this turn will run what was just
        queued (then a wake-up would only cost a turn with nothing ready)."""
        if self._guard and not self._in_waited_turn():
            self._guard.trigger()

    def _next_ready(self) -> tuple[Task[Any], None, None] | None:
        while self._ready and not self._is_shutdown:
            task = self._ready.popleft()
            if not (task.done() or task.executing() or getattr(task, 'parked', False)):
                return task, None, None
        return None

    def _next_after_turn(self) -> tuple[Task[Any], None, None] | None:
        if not self._after_turn or self._is_shutdown:
            return None
        task = self._after_turn.popleft()
        with self._tasks_lock:
            self._tasks.append((task, None, None))  # resumed like any task if it waits
        return task, None, None

    def _next_take(self) -> tuple[Task[None], Any, Node] | None:
        """The handler of the next message of a service or client taken from this turn: taken
        first, so that one with none left costs no task."""
        while self._taken and not self._is_shutdown:
            entity, node, take = self._taken.popleft()
            group = entity.callback_group
            if not self.can_execute(entity) or not group.beginning_execution(entity):
                continue
            execute = take(entity)
            if execute is None:
                group.ending_execution(entity)
                continue
            self._taken.append((entity, node, take))
            task = _ParkingTask(self, self._run_taken, (entity, execute), {})
            with self._tasks_lock:
                self._tasks.append((task, entity, node))
            return task, entity, node
        return None

    async def _run_taken(self, entity: Any, execute: Execute) -> None:
        """The callback of a message `_next_take` took, within the entity's callback group."""
        with self._work_tracker:
            try:
                await execute()
            finally:
                entity.callback_group.ending_execution(entity)

    def _take_service(self, srv: Service[Any, Any]) -> Execute | None:
        """rclpy's take of one request, but None when there was none."""
        try:
            with srv.handle:
                request, header = srv.handle.service_take_request(srv.srv_type.Request)
        except InvalidHandle:
            return None
        if header is None:
            return None

        async def execute() -> None:
            response = await await_or_execute(srv.callback, request, srv.srv_type.Response())
            srv.send_response(response, header)

        return execute

    def _take_client(self, client: Client[Any, Any]) -> Execute | None:
        """rclpy's take of one response, but None when there was none."""
        try:
            with client.handle:
                header, response = client.handle.take_response(client.srv_type.Response)
        except InvalidHandle:
            return None
        if header is None:
            return None

        async def execute() -> None:
            future = take_pending(client, header.request_id.sequence_number)
            if future is not None and not future.done():  # else it was cancelled
                future.set_result(response)  # its done callbacks run now (rclpy_tools.calls)

        return execute

    def create_task(self, callback: Callable[..., Any], *args: Any, **kwargs: Any) -> Task[Any]:
        task = _ParkingTask(self, callback, args, kwargs)
        self._resume(task)
        return task

    def _make_handler(self, entity: Any, node: Node, take_from_wait_list: Take) -> Task[None]:
        """The handler of a ready entity (a service request, a message), as a parking task (see
        `_handler_task`). A service or client it takes a message from is noted, to be taken from
        again at the end of the turn."""
        take = take_from_wait_list
        if isinstance(entity, Service | Client):

            def take(taken_from: Any) -> Execute | None:
                execute = take_from_wait_list(taken_from)
                if execute is not None:
                    self._taken.append((taken_from, node, take_from_wait_list))
                return execute

        self._waited = True  # rclpy makes handlers for what its wait found
        return super()._make_handler(entity, node, take)

    def _handler_task(self, entity: Any, take: Take) -> Task[None]:
        """An async callback awaiting a future (ExecuteTask's get_result answers, one per task in
        flight) waits off the list like any coroutine here."""
        return _ParkingTask(self, self._handle, (entity, take), {})

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
        self._wake()
