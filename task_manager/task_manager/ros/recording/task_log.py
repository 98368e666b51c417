"""The log lines of each task, without rclpy's lookup of the caller on every call.

rclpy's `RcutilsLogger.log` finds where it was called from with `inspect.getframeinfo`, which
reads the caller's source lines, and `os.path.abspath`, on every call: with one line per
task, that was 15 % of the node's time in a burst of instant tasks (docs/benchmarks.md). The
lines here go to the same rcutils logger, with the same severity, name and origin (function,
file, line); what rclpy adds for its filters (once, throttle, skip_first) is not needed here.
"""

import sys

from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.logging import LoggingSeverity


def _log(logger: RcutilsLogger, severity: LoggingSeverity, message: str) -> None:
    if not logger.is_enabled_for(severity):
        return
    caller = sys._getframe(2)
    code = caller.f_code
    _rclpy.rclpy_logging_rcutils_log(
        severity, logger.name, message, code.co_name, code.co_filename, caller.f_lineno
    )


def info(logger: RcutilsLogger, message: str) -> None:
    _log(logger, LoggingSeverity.INFO, message)


def warning(logger: RcutilsLogger, message: str) -> None:
    _log(logger, LoggingSeverity.WARN, message)
