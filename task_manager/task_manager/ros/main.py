"""Console entry point `task-manager`: runs the node named `task_manager`.

SIGINT and SIGTERM shut the node down cleanly: running tasks are cancelled on their
servers and their results published before the process exits 0. A second signal exits
at once. The signals are blocked in every thread and received by one thread that
waits for them, which wakes the executor through a guard condition.
"""

import signal

# Blocked before anything starts a thread (rclpy's import pulls in numpy, whose thread
# pool would otherwise receive the signals), so that every thread inherits the mask.
SHUTDOWN_SIGNALS = {signal.SIGINT, signal.SIGTERM}
signal.pthread_sigmask(signal.SIG_BLOCK, SHUTDOWN_SIGNALS)

import sys  # noqa: E402
import threading  # noqa: E402

import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.guard_condition import GuardCondition  # noqa: E402
from rclpy.logging import get_logger  # noqa: E402
from rclpy.signals import SignalHandlerOptions  # noqa: E402
from rclpy.task import Future  # noqa: E402

from task_manager.core.errors import ConfigurationError  # noqa: E402
from task_manager.ros.cleanup import destroy_waitables  # noqa: E402
from task_manager.ros.node import NODE_NAME, TaskManagerNode  # noqa: E402

EXIT_CONFIGURATION_ERROR = 2
DRAIN_MAX_CALLBACKS = 1000


def _receive_signals(shutdown_requested: GuardCondition, stopped: Future) -> None:
    signal.sigwait(SHUTDOWN_SIGNALS)
    shutdown_requested.trigger()
    signal.sigwait(SHUTDOWN_SIGNALS)
    get_logger(NODE_NAME).warning('second signal: exiting without waiting for tasks')
    if not stopped.done():
        stopped.set_result(False)
    shutdown_requested.trigger()


def _drain(executor: SingleThreadedExecutor) -> None:
    """Run the work that is ready (e.g. sending the last goal results) without waiting."""
    for _ in range(DRAIN_MAX_CALLBACKS):
        try:
            executor.spin_once(timeout_sec=0.0)
        except Exception:  # nothing left, or the context is going
            return


def main(args: list[str] | None = None) -> int:
    """Start the node with the ROS arguments given (e.g. `--ros-args --params-file F`)."""
    rclpy.init(
        args=args if args is not None else sys.argv,
        signal_handler_options=SignalHandlerOptions.NO,
    )
    executor = SingleThreadedExecutor()
    try:
        node = TaskManagerNode()
    except ConfigurationError as error:
        get_logger(NODE_NAME).fatal(f'invalid configuration: {error}')
        rclpy.try_shutdown()
        return EXIT_CONFIGURATION_ERROR
    stopped: Future = Future()
    shutdown_requested = node.create_guard_condition(
        lambda: executor.create_task(node.shut_down(stopped))
    )
    threading.Thread(
        target=_receive_signals, args=(shutdown_requested, stopped), daemon=True
    ).start()
    executor.add_node(node)
    try:
        executor.spin_until_future_complete(stopped)
        _drain(executor)
    finally:
        executor.shutdown()
        destroy_waitables(node)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
