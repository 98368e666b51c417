"""The `task_manager` node."""

from rclpy.node import Node

NODE_NAME = 'task_manager'


class TaskManagerNode(Node):
    """Serves the Task Manager's public ROS interfaces."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        self.get_logger().info('Task Manager ready')
