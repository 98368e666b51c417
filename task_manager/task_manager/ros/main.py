"""Console entry point `task-manager`: runs the node named `task_manager`."""

import sys

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.logging import get_logger

from task_manager.core.errors import ConfigurationError
from task_manager.ros.node import NODE_NAME, TaskManagerNode

EXIT_CONFIGURATION_ERROR = 2


def main(args: list[str] | None = None) -> int:
    """Start the node with the ROS arguments given (e.g. `--ros-args --params-file F`)."""
    rclpy.init(args=args if args is not None else sys.argv)
    node = None
    executor = SingleThreadedExecutor()
    try:
        node = TaskManagerNode()
        executor.add_node(node)
        executor.spin()
    except ConfigurationError as error:
        get_logger(NODE_NAME).fatal(f'invalid configuration: {error}')
        return EXIT_CONFIGURATION_ERROR
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
