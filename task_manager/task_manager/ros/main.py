"""Console entry point `task-manager`: runs the node named `task_manager`."""

import sys

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

from task_manager.ros.node import TaskManagerNode


def main(args: list[str] | None = None) -> int:
    """Start the node with the ROS arguments given (e.g. `--ros-args --params-file F`)."""
    rclpy.init(args=args if args is not None else sys.argv)
    node = TaskManagerNode()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
