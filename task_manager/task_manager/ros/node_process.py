"""Running the node until SIGINT/SIGTERM, then shutting it down cleanly (see main.py)."""

import signal
import threading

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.logging import get_logger
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

from task_manager.core.errors import ConfigurationError
from task_manager.core.params_file import check_params_file, params_files
from task_manager.ros.cleanup import destroy_waitables
from task_manager.ros.futures import wake
from task_manager.ros.node import NODE_NAME, TaskManagerNode

EXIT_CONFIGURATION_ERROR = 2
DRAIN_MAX_CALLBACKS = 1000


def _receive_signals(
    node: TaskManagerNode, stopped: Future, shutdown_signals: set[signal.Signals]
) -> None:
    signal.sigwait(shutdown_signals)
    assert node.executor is not None
    node.executor.create_task(node.shut_down, stopped)
    signal.sigwait(shutdown_signals)
    get_logger(NODE_NAME).warning('second signal: exiting without waiting for tasks')
    if not stopped.done():
        stopped.set_result(False)
    wake(node)


def _drain(executor: SingleThreadedExecutor) -> None:
    """Run the work that is ready (e.g. sending the last goal results) without waiting."""
    for _ in range(DRAIN_MAX_CALLBACKS):
        try:
            executor.spin_once(timeout_sec=0.0)
        except Exception:  # nothing left, or the context is going
            return


def _refuse_configuration(error: Exception) -> int:
    """One line saying what is wrong with the configuration; the exit code that says so."""
    what = (
        str(error) if isinstance(error, ConfigurationError) else f'{type(error).__name__}: {error}'
    )
    get_logger(NODE_NAME).fatal('invalid configuration: ' + ' '.join(what.split()))
    return EXIT_CONFIGURATION_ERROR


def run(args: list[str], shutdown_signals: set[signal.Signals]) -> int:
    """Run the node; `shutdown_signals` must already be blocked in every thread."""
    try:
        for path in params_files(args):
            check_params_file(path)
    except ConfigurationError as error:
        return _refuse_configuration(error)
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as error:  # rcl refuses the arguments or the parameters file
        return _refuse_configuration(error)
    executor = SingleThreadedExecutor()
    try:
        node = TaskManagerNode()
    except Exception as error:  # a value rclpy refuses (a list of mixed types, a bad name)
        rclpy.try_shutdown()
        return _refuse_configuration(error)
    stopped: Future = Future()
    executor.add_node(node)
    threading.Thread(
        target=_receive_signals, args=(node, stopped, shutdown_signals), daemon=True
    ).start()
    try:
        executor.spin_until_future_complete(stopped)
        _drain(executor)
    finally:
        executor.shutdown()
        destroy_waitables(node)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
