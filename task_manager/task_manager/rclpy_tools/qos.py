"""QoS profiles of the Task Manager's ROS interfaces (see INTERFACES.md)."""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# Deep enough that a burst of hundreds of requests or results is not dropped.
DEEP_QUEUE_DEPTH = 1000

DEEP_RELIABLE = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=DEEP_QUEUE_DEPTH,
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
