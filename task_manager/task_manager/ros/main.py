"""Console entry point `task-manager`: runs the node named `task_manager`.

SIGINT and SIGTERM shut the node down cleanly: running tasks are cancelled on their
servers and their results published before the process exits 0. A second signal exits
at once. The signals are blocked in every thread and received by one thread that
waits for them and hands the shutdown to the executor as a task.
"""

import sys

from task_manager.process_setup import block_stop_signals, prepare_ros_process


def main(args: list[str] | None = None) -> int:
    """Start the node with the ROS arguments given (e.g. `--ros-args --params-file F`)."""
    # Blocked before anything starts a thread, so that every thread inherits the mask:
    # importing rclpy pulls in numpy, whose thread pool would otherwise get the signals.
    # Hence the node's modules are imported only now, and importing this module has no
    # effect on the importer's signals.
    block_stop_signals()
    prepare_ros_process()
    from task_manager.ros.node_process import run

    return run(args if args is not None else sys.argv)


if __name__ == '__main__':
    sys.exit(main())
