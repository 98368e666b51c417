"""A SingleThreadedExecutor whose handlers do not wake its own wait, and whose wait set is
kept between turns.

rclpy's handler of a ready entity (Executor._make_handler in 9.1.2) triggers the executor's
guard condition twice: once its message is taken and once its callback has run, so that a wait
set built meanwhile by another thread takes the entity back. With one thread, every wait set
is built in it after the handler has run, so each trigger only makes the next wait return at
once with nothing ready: every message cost two wait sets built in Python, where one does.
Here the handler is rclpy's without those two wake-ups; a handler whose callback group is busy
still wakes the executor (the entity is left for a later wait, as in rclpy).

rclpy also builds each wait set anew (see reusable_wait_set); here a turn is rclpy's (the tasks in
progress, one wait, the ready waitables then each node's ready timers, subscriptions, guard
conditions, clients and services, a timeout as rclpy's) over a wait set kept while the nodes'
entities stay the same and all may run. A turn in which some may not (a handler's callback
group busy) waits on the others with a wait set made for it, as rclpy's does.

rclpy's take of a timer looks up, at each call, whether its callback takes a TimerInfo
(`inspect.signature`, a third of a millisecond, more than most of the node's timer callbacks);
here it is looked up once per callback of a timer.

The client's executor (every message of a gateway's node, three to seven per task) and the
node's ParkingExecutor both use it.
"""

import functools
import inspect
import time
from collections.abc import Callable, Coroutine, Generator, Iterator
from typing import Any

from rclpy.exceptions import InvalidHandle, TimerCancelledError
from rclpy.executors import (
    ConditionReachedException,
    ExternalShutdownException,
    ShutdownException,
    SingleThreadedExecutor,
    TimeoutException,
    TimeoutObject,
)
from rclpy.node import Node
from rclpy.task import Task
from rclpy.timer import Timer, TimerInfo
from rclpy.utilities import timeout_sec_to_nsec

from task_manager.rclpy_tools.reusable_wait_set import NodeEntities, Ready, ReusableWaitSet

Execute = Callable[[], Coroutine[None, None, None]]
Take = Callable[[Any], Execute | None]
Work = tuple[Task[Any], Any, Node | None]
# rclpy's take of each kind of entity
_TAKES = {
    'timer': '_take_timer',
    'subscription': '_take_subscription',
    'guard_condition': '_take_guard_condition',
    'client': '_take_client',
    'service': '_take_service',
}


class WakelessExecutor(SingleThreadedExecutor):
    """rclpy's SingleThreadedExecutor, its ready entities handled without waking it, its wait
    set kept between turns."""

    _kept: ReusableWaitSet | None = None

    def _wait_for_ready_callbacks(
        self,
        timeout_sec: float | TimeoutObject | None = None,
        nodes: list[Node] | None = None,
        condition: Callable[[], bool] = lambda: False,
    ) -> Generator[Work, None, None]:
        """rclpy's turns until one yields work, the executor shuts down or `condition` holds;
        TimeoutException once `timeout_sec` has passed (at once for 0)."""
        if isinstance(timeout_sec, TimeoutObject):
            timeout_sec = timeout_sec.timeout
        timeout_nsec = timeout_sec_to_nsec(timeout_sec)
        deadline = time.monotonic_ns() + timeout_nsec if timeout_nsec > 0 else None
        yielded = False
        while not yielded and not self._is_shutdown and not condition():
            in_use = self.get_nodes() if nodes is None else nodes
            for work in self._tasks_in_progress(in_use):
                yielded = True
                yield work
            wait_set = self._wait_set_for(in_use)
            if deadline is not None:
                timeout_nsec = max(deadline - time.monotonic_ns(), 0)
            try:
                ready, ready_waitables = wait_set.wait(timeout_nsec)
            except InvalidHandle:  # destroyed by another thread since: made again, without it
                self._kept = None
                continue
            if self._is_shutdown:
                ready_waitables.close()
                raise ShutdownException()
            if not self._context.ok():
                ready_waitables.close()
                raise ExternalShutdownException()
            for found in ready_waitables:  # while the handles are held, as rclpy
                waitable, node = found.entity, found.node
                if waitable.callback_group.can_execute(waitable):
                    yielded = True
                    yield self._make_handler(waitable, node, self._take_waitable), waitable, node
            for work in self._handlers(ready):
                yielded = True
                yield work
            if timeout_nsec == 0 or (deadline is not None and time.monotonic_ns() >= deadline):
                raise TimeoutException()
        if self._is_shutdown:
            raise ShutdownException()
        if condition():
            raise ConditionReachedException()

    def _tasks_in_progress(self, nodes: list[Node]) -> Iterator[Work]:
        """rclpy's tasks not yet done of these nodes (or of none), the done ones then dropped."""
        with self._tasks_lock:
            tasks = list(self._tasks)
        if not tasks:
            return
        for task, entity, node in tasks:
            if not task.executing() and not task.done() and (node is None or node in nodes):
                yield task, entity, node
        with self._tasks_lock:
            self._tasks = [
                entry for entry in self._tasks if not (entry[0].done() or entry[0].cancelled())
            ]

    def _wait_set_for(self, nodes: list[Node]) -> ReusableWaitSet:
        """The kept wait set, made again if the nodes' entities changed; when some may not run
        now, one for this turn of those that may."""
        entities = [NodeEntities.of(node) for node in nodes]
        own_guards = [guard for guard in (self._guard, self._sigint_gc) if guard]
        kept = self._kept
        if kept is None or kept.entities != entities or kept.own_guards != own_guards:
            kept = self._kept = ReusableWaitSet(entities, own_guards, self._context, kept)
        for node_entities in entities:
            for guard in node_entities.guards:
                if guard._executor_triggered:  # triggered, not yet handled: rclpy's retrigger
                    guard.trigger()
        if kept.all_can_execute():
            return kept
        return ReusableWaitSet(
            [node_entities.executable(self.can_execute) for node_entities in entities],
            own_guards,
            self._context,
            kept,
        )

    def _handlers(self, ready: list[Ready]) -> Iterator[Work]:
        for found in ready:
            if found.kind == 'guard_condition':
                found.entity._executor_triggered = True
        for found in ready:
            entity, node = found.entity, found.node
            group = entity.callback_group
            if found.kind == 'timer' and not entity.handle.is_timer_ready():
                continue  # rclpy's workaround of rcl's cancelled timers
            if found.kind == 'guard_condition' and not entity._executor_triggered:
                continue
            if group is not None and group.can_execute(entity):
                take = getattr(self, _TAKES[found.kind])
                yield self._make_handler(entity, node, take), entity, node

    def _take_timer(self, tmr: Timer) -> Execute | None:
        """rclpy's take of a timer (its call counted), what its callback takes looked up once
        per callback; None if the timer is gone or was cancelled."""
        try:
            with tmr.handle:
                info = tmr.handle.call_timer_with_info()
        except (InvalidHandle, TimerCancelledError):
            return None
        callback: Callable[..., Any] | None = tmr.callback
        if callback is None:
            return None
        arg_name, is_coroutine = _timer_callback_kind(tmr, callback)
        call: Callable[[], Any] = callback
        if arg_name is not None:
            timer_info = TimerInfo(
                expected_call_time=info['expected_call_time'],
                actual_call_time=info['actual_call_time'],
                clock_type=tmr.clock.clock_type,
            )
            call = functools.partial(callback, **{arg_name: timer_info})

        async def execute() -> None:
            if is_coroutine:
                await call()
            else:
                call()

        return execute

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        done = super().shutdown(timeout_sec)
        self._kept = None
        return done

    def _make_handler(self, entity: Any, node: Node, take_from_wait_list: Take) -> Task[None]:
        entity._executor_event = True  # out of the wait sets until its message is taken
        task = self._handler_task(entity, take_from_wait_list)
        with self._tasks_lock:
            self._tasks.append((task, entity, node))
        return task

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


def _timer_callback_kind(timer: Timer, callback: Callable[..., Any]) -> tuple[str | None, bool]:
    """The name of the callback's parameter annotated TimerInfo (None: it takes none) and
    whether it is a coroutine function, kept on the timer for as long as its callback is the
    same."""
    kept = getattr(timer, '_task_manager_callback_kind', None)
    if kept is not None and kept[0] is callback:
        known: tuple[str | None, bool] = kept[1]
        return known
    name = next(
        (
            parameter.name
            for parameter in inspect.signature(callback).parameters.values()
            if parameter.annotation == TimerInfo
        ),
        None,
    )
    kind = (name, inspect.iscoroutinefunction(callback))
    timer._task_manager_callback_kind = (callback, kind)  # type: ignore[attr-defined]
    return kind
