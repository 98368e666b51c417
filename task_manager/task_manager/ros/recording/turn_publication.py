"""A publication that gathers the changes of an executor turn, and of longer when it is large.

Used for lists that say the whole state at once (active_tasks, an action's status array):
`changed()` asks for one publication after the executor has handled what is ready now; while
the list is large, publications are at least 1 / rate_hz seconds apart and the changes of that
time share one. A timer waits out the gap: nothing polls.
"""

import time
from collections.abc import Callable

from rclpy.node import Node
from rclpy.timer import Timer

from task_manager.rclpy_tools.cleanup import destroy_timer
from task_manager.ros.parking_executor import spawn_after_turn


class TurnPublication:
    """Calls `publish` once per executor turn with changes; rate-bounded while `is_large()`."""

    def __init__(
        self,
        node: Node,
        publish: Callable[[], None],
        is_large: Callable[[], bool],
        rate_hz: float,
    ) -> None:
        self._node = node
        self._publish = publish
        self._is_large = is_large
        self._period_sec = 1.0 / rate_hz
        self._pending = False
        self._last_published = -float('inf')
        self._timer: Timer | None = None

    def changed(self) -> None:
        if not self._pending:
            self._pending = True
            spawn_after_turn(self._node, self._after_turn())

    async def _after_turn(self) -> None:
        wait_sec = self._last_published + self._period_sec - time.monotonic()
        if wait_sec > 0 and self._is_large():
            self._timer = self._node.create_timer(wait_sec, self._on_timer)
            return  # still pending: changes meanwhile join this publication
        self._publish_now()

    def _on_timer(self) -> None:
        if self._timer is not None:
            destroy_timer(self._node, self._timer)
            self._timer = None
        self._publish_now()

    def _publish_now(self) -> None:
        self._pending = False
        self._last_published = time.monotonic()
        self._publish()
