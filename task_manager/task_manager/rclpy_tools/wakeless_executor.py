"""A SingleThreadedExecutor whose handlers do not wake its own wait, and which takes the next
messages of what it took from before it waits again.

rclpy's handler of a ready entity (Executor._make_handler in 9.1.2) triggers the executor's
guard condition twice: once its message is taken and once its callback has run, so that a wait
set built meanwhile by another thread takes the entity back. With one thread, every wait set
is built in it after the handler has run, so each trigger only makes the next wait return at
once with nothing ready: every message cost two wait sets built in Python, where one does.
Here the handler is rclpy's without those two wake-ups; a handler whose callback group is busy
still wakes the executor (the entity is left for a later wait, as in rclpy).

rclpy takes one message per entity per wait: a reader behind by 500 messages (a gateway
during a burst of tasks) built 500 wait sets. Here a subscription, a service or a client that
a message was taken from in a turn is taken from again at the turn's end, at most
TAKE_AGAIN_LIMIT times in all, until it has none; the entities found ready by one wait are all
handled before any of them is taken from again.

The client's executor (every message of a gateway's node) and the node's ParkingExecutor,
which adds its own work to the end of a turn, both use it.
"""

from collections import deque
from collections.abc import Callable, Coroutine, Iterator
from typing import Any

from rclpy.client import Client
from rclpy.context import Context
from rclpy.exceptions import InvalidHandle
from rclpy.executors import SingleThreadedExecutor, TimeoutException, await_or_execute
from rclpy.node import Node
from rclpy.service import Service
from rclpy.subscription import Subscription
from rclpy.task import Task

Execute = Callable[[], Coroutine[None, None, None]]
Take = Callable[[Any], Execute | None]
Work = tuple[Task[Any], Any, Node | None]
# messages taken again at the end of a turn, before the executor waits again
TAKE_AGAIN_LIMIT = 100
_TAKEN_AGAIN = (Subscription, Service, Client)


class WakelessExecutor(SingleThreadedExecutor):
    """rclpy's SingleThreadedExecutor, its ready entities handled without waking it, and taken
    from again before it waits (see the module)."""

    def __init__(self, *, context: Context | None = None) -> None:
        super().__init__(context=context)
        # what a message was taken from this turn: maybe more are waiting
        self._taken: deque[tuple[Any, Node, Take]] = deque()

    def _wait_for_ready_callbacks(self, *args: Any, **kwargs: Any) -> Any:
        """rclpy's turn (the tasks in progress, a wait, the entities found ready), then the rest
        of the turn (`_rest_of_turn`) before the next wait."""
        self._begin_turn()
        try:
            yield from super()._wait_for_ready_callbacks(*args, **kwargs)
        except TimeoutException:
            if not self._has_rest_of_turn():
                raise  # nothing left of this turn: spin_once(timeout) returns
        yield from self._rest_of_turn()

    def _begin_turn(self) -> None:
        """Called as a turn begins, before its wait."""

    def _has_rest_of_turn(self) -> bool:
        return bool(self._taken)

    def _rest_of_turn(self) -> Iterator[Work]:
        """The next messages of what this turn took from, at most TAKE_AGAIN_LIMIT."""
        for _ in range(TAKE_AGAIN_LIMIT):
            work = self._next_take()
            if work is None:
                break
            yield work
        self._taken.clear()

    def _next_take(self) -> Work | None:
        while self._taken and not self._is_shutdown:
            entity, node, take = self._taken.popleft()
            if self.can_execute(entity):
                return self._make_handler(entity, node, take), entity, node
        return None

    def _make_handler(self, entity: Any, node: Node, take_from_wait_list: Take) -> Task[None]:
        take = take_from_wait_list
        if isinstance(entity, _TAKEN_AGAIN):

            def take(taken_from: Any) -> Execute | None:
                execute = take_from_wait_list(taken_from)
                if execute is not None:
                    self._taken.append((taken_from, node, take_from_wait_list))
                return execute

        entity._executor_event = True  # out of the wait sets until its message is taken
        task = self._handler_task(entity, take)
        with self._tasks_lock:
            self._tasks.append((task, entity, node))
        return task

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
            try:
                future = client.get_pending_request(header.request_id.sequence_number)
            except KeyError:
                return  # the request was cancelled
            future._set_executor(self)
            future.set_result(response)

        return execute

    def _handler_task(self, entity: Any, take: Take) -> Task[None]:
        """The task that runs `_handle` (a subclass may make another kind)."""
        return Task(self._handle, (entity, take), executor=self)

    async def _handle(self, entity: Any, take: Take) -> None:
        """Take the entity's message, run its callback, within its callback group."""
        group = entity.callback_group
        if self._is_shutdown or (group is not None and not group.beginning_execution(entity)):
            entity._executor_event = False
            if self._guard:
                self._guard.trigger()
            return
        with self._work_tracker:
            execute = take(entity)
            entity._executor_event = False
            try:
                if execute is not None:
                    await execute()
            finally:
                if group is not None:
                    group.ending_execution(entity)
