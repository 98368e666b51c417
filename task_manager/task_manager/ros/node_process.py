"""Running the node until SIGINT/SIGTERM, then shutting it down cleanly (see main.py)."""

import gc
import os
import signal
import sys
import threading
import traceback
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, ShutdownException, SingleThreadedExecutor
from rclpy.logging import get_logger
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

from task_manager.core.errors import ConfigurationError
from task_manager.core.names import EXECUTE_TASK_ACTION, NODE_NAME
from task_manager.core.params_file import check_params_file, params_files
from task_manager.middleware_watchdog import MiddlewareWatchdog
from task_manager.process_setup import EXIT_START_AGAIN, STOP_SIGNALS, end_within
from task_manager.rclpy_tools.futures import wake
from task_manager.rclpy_tools.log import log_warnings
from task_manager.ros import parking_executor
from task_manager.ros.instances import describe
from task_manager.ros.node import TaskManagerNode
from task_manager.ros.parking_executor import ParkingExecutor

PROGRAM = 'task-manager'
EXIT_CONFIGURATION_ERROR = 2
EXIT_ANOTHER_TASK_MANAGER = 2
EXIT_MIDDLEWARE_STUCK = EXIT_START_AGAIN
DRAIN_MAX_CALLBACKS = 1000
YOUNG_COLLECTION_THRESHOLD = 7000


def _receive_signals(node: TaskManagerNode, stopped: Future[Any]) -> None:
    signal.sigwait(STOP_SIGNALS)
    assert node.executor is not None
    node.executor.create_task(node.shut_down, stopped)
    signal.sigwait(STOP_SIGNALS)
    get_logger(NODE_NAME).warning('second signal: exiting without waiting for tasks')
    if not stopped.done():
        stopped.set_result(False)
    wake(node)


def _drain(executor: SingleThreadedExecutor) -> None:
    """Run the work that is ready (e.g. sending the last goal results) without waiting: until
    nothing is ready (bounded, in case the work keeps making more)."""
    for _ in range(DRAIN_MAX_CALLBACKS):
        try:
            handler, _, _ = executor.wait_for_ready_callbacks(timeout_sec=0.0)
            handler()
        except Exception:  # nothing is ready (TimeoutException), or the context is going
            return


def _serve_until(executor: SingleThreadedExecutor, stopped: Future[Any]) -> None:
    """Spin until `stopped`. An exception a callback lets out (a bug of ours) is logged in one
    line, where it was raised, and the node goes on serving: exiting would leave every running
    goal untracked and every client without its result."""
    while not stopped.done():
        try:
            executor.spin_until_future_complete(stopped)
        except (ExternalShutdownException, ShutdownException):
            raise
        except Exception as error:
            where = traceback.extract_tb(error.__traceback__)[-1]
            get_logger(NODE_NAME).error(
                f'a callback failed and was dropped, the Task Manager goes on: {error!r} '
                f'at {where.filename}:{where.lineno} ({where.name})'
            )


def _refuse_configuration(error: Exception) -> int:
    """One line saying what is wrong with the configuration; the exit code that says so."""
    what = (
        str(error) if isinstance(error, ConfigurationError) else f'{type(error).__name__}: {error}'
    )
    get_logger(NODE_NAME).fatal('invalid configuration: ' + ' '.join(what.split()))
    return EXIT_CONFIGURATION_ERROR


def run(args: list[str]) -> int:
    """Run the node; STOP_SIGNALS must already be blocked in every thread."""
    try:
        for path in params_files(args):
            check_params_file(path)
    except ConfigurationError as error:
        return _refuse_configuration(error)
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as error:  # rcl refuses the arguments or the parameters file
        return _refuse_configuration(error)
    log_warnings(get_logger(NODE_NAME))
    parking_executor.install()
    executor = ParkingExecutor()
    try:
        node = TaskManagerNode()
    except Exception as error:  # a value rclpy refuses (a list of mixed types, a bad name)
        rclpy.try_shutdown()
        return _refuse_configuration(error)
    code = 1  # an error of ours, raised on
    try:
        code = _serve(executor, node)
    finally:
        node.close_history()  # before the bound: the ends are written whatever DDS does
        end_within(lambda: _release(executor, node), PROGRAM, code)
    return code


def _serve(executor: SingleThreadedExecutor, node: TaskManagerNode) -> int:
    """Serve until a shutdown signal (or an older Task Manager found); the exit code."""
    stopped: Future[Any] = Future()
    exit_code = [0]
    executor.add_node(node)
    executor.spin_until_future_complete(
        node.instances.older, timeout_sec=node.settings.instance_check_timeout_sec
    )
    if node.instances.older.done():
        _report_older(node, 'not starting')
        return EXIT_ANOTHER_TASK_MANAGER
    node.serve()
    _tune_garbage_collection()
    node.instances.older.add_done_callback(lambda _: _yield_to_older(node, stopped, exit_code))
    threading.Thread(target=_receive_signals, args=(node, stopped), daemon=True).start()
    watchdog = _watch_the_middleware(node.settings.middleware_watchdog_timeout_sec)
    try:
        _serve_until(executor, stopped)
        _drain(executor)
    finally:
        if watchdog is not None:
            watchdog.stop()
    return exit_code[0]


def _tune_garbage_collection() -> None:
    """What start-up made lives as long as the node: frozen, no collection walks it again; and
    the youngest generation collected every YOUNG_COLLECTION_THRESHOLD allocations instead of
    Python's 700 (a task allocates hundreds of objects, few of them in cycles). Measured, 1,500
    instant tasks in bursts: 191 collections took 84 ms of the node's CPU, 4 took 7 ms."""
    gc.freeze()
    _, middle, old = gc.get_threshold()
    gc.set_threshold(YOUNG_COLLECTION_THRESHOLD, middle, old)


def _watch_the_middleware(timeout_sec: float) -> MiddlewareWatchdog | None:
    """A watchdog that ends the process when DDS is stuck (see middleware_watchdog); none with
    a timeout of 0."""
    if timeout_sec <= 0:
        return None
    watchdog = MiddlewareWatchdog(timeout_sec, _exit_stuck)
    watchdog.start()
    return watchdog


def _exit_stuck(message: str) -> None:
    """The middleware is stuck: nothing can be sent or destroyed any more; one line, and out
    (what a turn of the executor had not written to the history yet is lost, as in a crash)."""
    get_logger(NODE_NAME).fatal(message)
    sys.stderr.flush()
    os._exit(EXIT_MIDDLEWARE_STUCK)


def _release(executor: SingleThreadedExecutor, node: TaskManagerNode) -> None:
    executor.shutdown()
    node.destroy_node()  # its action servers and clients first (TaskManagerNode.destroy_node)
    rclpy.try_shutdown()


def _report_older(node: TaskManagerNode, what: str) -> None:
    older = node.instances.older.result()
    assert older is not None
    get_logger(NODE_NAME).fatal(
        f'{what}: another Task Manager already serves {EXECUTE_TASK_ACTION} on ROS domain '
        f'{node.context.get_domain_id()} ({describe(older)}); stop it first, or give this one '
        'another ROS_DOMAIN_ID'
    )


def _yield_to_older(node: TaskManagerNode, stopped: Future[Any], exit_code: list[int]) -> None:
    """An older Task Manager was discovered late: this one stops as if signalled, exit 2."""
    _report_older(node, 'stopping')
    exit_code[0] = EXIT_ANOTHER_TASK_MANAGER
    assert node.executor is not None
    node.executor.create_task(node.shut_down, stopped)
