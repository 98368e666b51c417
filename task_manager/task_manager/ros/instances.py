"""One Task Manager per ROS domain: each announces itself, and the younger of two yields.

Two Task Managers serving `/task_manager/execute_task` would both accept every goal: each
task would run twice, and each would cancel the other's blocking tasks. Every Task Manager
publishes a TaskManagerInstance once on a transient-local topic, so every other one, however
late it discovers it, receives it. The younger of two (later `started`, then the greater
`instance_id`) learns it is the younger and stops; the older goes on undisturbed.
"""

import os
import socket
import time
import uuid
from datetime import datetime

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from task_manager_msgs.msg import TaskManagerInstance

from task_manager.core.names import INSTANCES_TOPIC
from task_manager.messages.task_messages import stamp
from task_manager.rclpy_tools.qos import subscription_without_qos_events, without_qos_events

# Each publisher keeps its one message for subscribers that join later.
INSTANCES_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

# Each subscriber keeps every message until it is taken. The topic has no key: with a depth
# of 1, a message not yet taken is replaced by the next one from any publisher. A Task
# Manager's own announcement, published a moment after an older one's had arrived, replaced
# it: the younger never saw the older and served beside it (DDS acknowledges the replaced
# message, so it is never sent again).
INSTANCES_SUBSCRIPTION_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_ALL,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)


def this_instance() -> TaskManagerInstance:
    return TaskManagerInstance(
        started=stamp(time.time()),
        host=socket.gethostname(),
        pid=os.getpid(),
        instance_id=str(uuid.uuid4()),
    )


def _age_key(instance: TaskManagerInstance) -> tuple[int, int, str]:
    """Orders instances from the oldest."""
    return (instance.started.sec, instance.started.nanosec, instance.instance_id)


def describe(instance: TaskManagerInstance) -> str:
    """E.g. "pid 4711 on host robot-1, started 2026-11-23 14:02:11"."""
    started = datetime.fromtimestamp(instance.started.sec).isoformat(sep=' ')
    return f'pid {instance.pid} on host {instance.host!r}, started {started}'


class InstanceWatch:
    """Announces this Task Manager; `older` completes with an older one once one is seen."""

    def __init__(self, node: Node) -> None:
        self.own = this_instance()
        self.older: Future[TaskManagerInstance] = Future()
        self._publisher = node.create_publisher(
            TaskManagerInstance,
            INSTANCES_TOPIC,
            INSTANCES_QOS,
            event_callbacks=without_qos_events(),
        )
        self._subscription = node.create_subscription(
            TaskManagerInstance,
            INSTANCES_TOPIC,
            self._on_instance,
            INSTANCES_SUBSCRIPTION_QOS,
            event_callbacks=subscription_without_qos_events(),
        )
        self._publisher.publish(self.own)

    def _on_instance(self, other: TaskManagerInstance) -> None:
        if self.older.done() or other.instance_id == self.own.instance_id:
            return
        if _age_key(other) < _age_key(self.own):
            self.older.set_result(other)
