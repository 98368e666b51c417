"""Timers the node makes per task leave nothing behind once destroyed."""

import pytest

from task_manager.rclpy_tools.cleanup import destroy_timer
from task_manager.testing.harness import RosHarness

pytestmark = pytest.mark.ros
TIMERS = 100


def test_a_destroyed_timer_leaves_nothing_in_its_callback_group(ros: RosHarness) -> None:
    group = ros.node.default_callback_group
    before = len(group.entities)
    for _ in range(TIMERS):
        destroy_timer(ros.node, ros.node.create_timer(60.0, lambda: None))
    # rclpy's destroy_timer alone leaves each timer's weak reference there
    assert len(group.entities) == before
