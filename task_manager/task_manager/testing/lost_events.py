"""Task event batches published by a test, standing in for the node's writer (the same topic and
QoS), to make a reader of them lose some: a client held up, or a gateway's process stopped,
while more come than the reader keeps."""

import os
import signal
from typing import Any

from task_manager_msgs.msg import TaskEvent, TaskEventArray

from task_manager.core.names import TASK_EVENT_BATCHES_TOPIC
from task_manager.rclpy_tools import qos
from task_manager.testing.gateway import wait_until
from task_manager.testing.harness import RosHarness

MORE_THAN_KEPT = 4 * qos.DEEP_QUEUE_DEPTH
"""Batches enough that a reader stopped meanwhile loses some: more than its depth and the
writer's, and than the transport's buffers hold of them."""


def event_batch(task_id: str) -> TaskEventArray:
    """A batch of one RECEIVED event of `task_id`, as the node publishes them."""
    event = TaskEvent(event='RECEIVED')
    event.task.task_id, event.task.task_name, event.task.task_status = task_id, 'fib', 'RECEIVED'
    return TaskEventArray(events=[event])


def batch_writer(ros: RosHarness, readers: int = 1) -> Any:
    """A publisher of task event batches, once `readers` readers of them match it."""
    writer = ros.on_executor(
        lambda: ros.node.create_publisher(TaskEventArray, TASK_EVENT_BATCHES_TOPIC, qos.TASK_EVENTS)
    )
    wait_until(lambda: writer.get_subscription_count() >= readers, 'the readers of the batches')
    return writer


def flood_while_stopped(writer: Any, pid: int, count: int = MORE_THAN_KEPT) -> None:
    """Publish `count` batches (tasks `b0`, `b1`, ...) while process `pid` is stopped
    (SIGSTOP, then SIGCONT), then one more (`after`) once the writer reaches it again: its
    reader, which must have taken a batch of this writer before, finds the gap (from the
    newest the writer kept for it, or from `after` if its lease ran out meanwhile and the
    writer dropped it)."""
    os.kill(pid, signal.SIGSTOP)
    try:
        for number in range(count):
            writer.publish(event_batch(f'b{number}'))
    finally:
        os.kill(pid, signal.SIGCONT)
    wait_until(lambda: writer.get_subscription_count() >= 1, 'the stopped reader again')
    writer.publish(event_batch('after'))
