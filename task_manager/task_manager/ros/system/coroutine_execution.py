"""An Execution whose work is a coroutine on the node's executor."""

from collections.abc import Coroutine
from typing import Any

from rclpy.node import Node
from rclpy.task import Future

from task_manager.core.task import TaskEnd
from task_manager.rclpy_tools.futures import wait_for


class CoroutineExecution:
    """Runs `body` to its TaskEnd; cancel waits (bounded) for it, as it cannot be interrupted."""

    def __init__(self, node: Node, body: Coroutine[Any, Any, TaskEnd]) -> None:
        self._node = node
        self.outcome: Future[Any] = Future()
        assert node.executor is not None
        node.executor.create_task(self._run, body)

    async def _run(self, body: Coroutine[Any, Any, TaskEnd]) -> None:
        end = await body
        if not self.outcome.done():
            self.outcome.set_result(end)

    async def cancel(self, timeout_sec: float) -> bool:
        return await wait_for(self._node, self.outcome, timeout_sec)
