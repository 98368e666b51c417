"""The executor tests' node: one of this test process, on an executor spun by the test."""

import os
from collections.abc import Iterator

import pytest
import rclpy
from rclpy.node import Node

from task_manager.rclpy_tools.wakeless_executor import WakelessExecutor


@pytest.fixture
def spun(
    ros_context: None, request: pytest.FixtureRequest
) -> Iterator[tuple[WakelessExecutor, Node]]:
    """A node on a WakelessExecutor, or on the executor class a test gives as the fixture's
    parameter (`indirect`)."""
    module = request.module.__name__.rpartition('.')[2]
    node = rclpy.create_node(f'{module}_{os.getpid()}')
    executor = getattr(request, 'param', WakelessExecutor)()
    executor.add_node(node)
    yield executor, node
    executor.shutdown()
    node.destroy_node()
