"""A SingleThreadedExecutor whose handlers do not wake its own wait.

rclpy's handler of a ready entity (Executor._make_handler in 9.1.2) triggers the executor's
guard condition twice: once its message is taken and once its callback has run, so that a wait
set built meanwhile by another thread takes the entity back. With one thread, every wait set
is built in it after the handler has run, so each trigger only makes the next wait return at
once with nothing ready: every message cost two wait sets built in Python, where one does.
Here the handler is rclpy's without those two wake-ups; a handler whose callback group is busy
still wakes the executor (the entity is left for a later wait, as in rclpy).

The client's executor (every message of a gateway's node, three to seven per task) and the
node's ParkingExecutor both use it.
"""

from collections.abc import Callable, Coroutine
from typing import Any

from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.task import Task

Execute = Callable[[], Coroutine[None, None, None]]
Take = Callable[[Any], Execute | None]


class WakelessExecutor(SingleThreadedExecutor):
    """rclpy's SingleThreadedExecutor, its ready entities handled without waking it."""

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
