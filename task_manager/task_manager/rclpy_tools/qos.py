"""QoS profiles of the Task Manager's ROS interfaces (see INTERFACES.md)."""

from typing import Any

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# Deep enough that a burst of hundreds of requests or results is not dropped.
DEEP_QUEUE_DEPTH = 1000

DEEP_RELIABLE = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=DEEP_QUEUE_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

# The replies to the node's GetResult requests: a server answers every request it holds as
# its goal ends, up to 8 per goal (the first and the asks again), so 1,000 goals ending at once
# may send 8,000 while the node is busy ending their tasks; a reader overwrites the oldest it
# has not read. Memory is taken as replies wait, not reserved for the depth.
RESULT_REPLIES = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10 * DEEP_QUEUE_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

ACTIVE_TASKS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

RESULTS = DEEP_RELIABLE

# Volatile: a subscriber that joins late asks /task_manager/get_task_states for the present.
TASK_EVENTS = DEEP_RELIABLE

# A subscriber that wants the current list only: of the history a transient-local
# publisher sends to a new subscriber, it keeps the newest message.
LATEST_ACTIVE_TASKS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

# A subscriber that wants every list from now on: deep enough that a burst of changes waits
# for it rather than being overwritten; transient local, so that the lists published while the
# writer is still learning of this reader come as history (it drops those that are over).
ACTIVE_TASK_CHANGES = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=DEEP_QUEUE_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)


def without_qos_events() -> PublisherEventCallbacks:
    """No incompatible-QoS handlers for a publisher of the node. rclpy adds two by default to
    each publisher and subscription, each one more waitable in every wait (at least three per
    task): they log that a reader asked for a QoS the publisher does not offer. The node's
    readers are made with its QoS (an action's status and feedback, the instance
    announcements), and a reader of its public topics made otherwise is told by its own
    handler, which rclpy and rclcpp add by default ("offering incompatible QoS")."""
    return PublisherEventCallbacks(use_default_callbacks=False)


def drop_qos_events(node: Node, publisher: Publisher[Any] | None) -> None:
    """Take out the incompatible-QoS handlers rclpy gave a publisher it made for the node
    (its /parameter_events), as `without_qos_events` does for the node's own."""
    if publisher is None:
        return
    for handler in publisher.event_handlers:
        node.remove_waitable(handler)
        handler.destroy()
    publisher.event_handlers.clear()


def subscription_without_qos_events() -> SubscriptionEventCallbacks:
    """The same for a subscription whose every writer is made with its QoS."""
    return SubscriptionEventCallbacks(use_default_callbacks=False)
