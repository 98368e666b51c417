"""A thread that spins an executor in the background, stopped and joined before its node goes.

rclpy's `Executor.shutdown()`, called from another thread, does not wait for the spinning
thread (its wait for callbacks in progress is skipped: the check reads the flag it has just
set) and destroys the executor's guard condition at once. A thread that gathered its wait set
in between waits without that guard, until something else wakes it; a process that then
destroys the node under the waiting thread can die of a segmentation fault (rclpy #663,
destroying a node that another thread spins). `SpinThread` is woken by a guard condition of the
node's own, which stays triggered until a wait takes it, so the wake-up cannot be lost, and
`stop` returns once the thread has ended: only then may the node be destroyed.
"""

import threading
from collections.abc import Callable

from rclpy.executors import Executor
from rclpy.node import Node


class SpinThread:
    """Spins `executor` (holding `node`) in a daemon thread named `name` until `stop`.

    What `spin_once` raises goes to `on_error` unless the thread is stopping or the context is
    going; `on_error` returns to spin on, or raises to end the thread. Without one, the error
    ends the thread, as it ends rclpy's `spin`.
    """

    def __init__(
        self,
        executor: Executor,
        node: Node,
        name: str,
        on_error: Callable[[Exception], None] | None = None,
    ) -> None:
        self._executor = executor
        self._node = node
        self._on_error = on_error
        self._stopping = False
        self._wake = node.create_guard_condition(lambda: None)
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        self._thread.start()

    def is_current(self) -> bool:
        """Whether the caller runs on this thread."""
        return threading.current_thread() is self._thread

    def stop(self, timeout_sec: float) -> bool:
        """Wake the thread, let it end its callback, join it; whether it ended in time. Again
        once stopped (a client closed twice), only the join: the node may be gone."""
        if not self._stopping:
            self._stopping = True
            self._wake.trigger()
        self._thread.join(timeout_sec)
        return not self._thread.is_alive()

    def _run(self) -> None:
        while not self._stopping and self._node.context.ok():
            try:
                self._executor.spin_once()
            except Exception as error:
                if self._stopping or not self._node.context.ok():
                    return
                if self._on_error is None:
                    raise
                self._on_error(error)
