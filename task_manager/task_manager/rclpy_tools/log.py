"""How the project's ROS processes write log lines (the node, and the client in a user's
process): `NodeLog`, rclpy's logger of a node without rclpy's lookup of the caller on each line.

rclpy's `RcutilsLogger.log` finds where it was called from with `inspect.getframeinfo`, which
reads the caller's source lines, and `os.path.abspath`, on every call: with one line per
task, that was 15 % of the node's time in a burst of instant tasks (docs/benchmarks.md). A
NodeLog writes to the same rcutils logger, with the same severity, name and origin (function,
file, line), through rclpy's own binding, which rclpy keeps private: where a version of rclpy
has it not, the line goes through `RcutilsLogger.log` (as it does for a stand-in logger, a
test's, that has only `log(message, severity)`). What rclpy adds for its filters (once,
throttle, skip_first) is not offered. Code without a node (the gateways, core) logs through
Python's `logging`. `log_warnings` makes Python's warnings lines of a logger (the node's).
"""

import sys
import warnings
from collections.abc import Callable
from typing import Any, TextIO

from rclpy.impl.logging_severity import LoggingSeverity
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node

try:
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

    _write: Any = _rclpy.rclpy_logging_rcutils_log
except (ImportError, AttributeError):  # pragma: no cover - another rclpy
    _write = None


class NodeLog:
    """The log of a node, or of one of its parts (`child`)."""

    def __init__(self, logger: RcutilsLogger) -> None:
        self.logger = logger

    @classmethod
    def of(cls, node: Node, child: str = '') -> 'NodeLog':
        """The log of `node` (`<node>.<child>` with a child)."""
        logger = node.get_logger()
        return cls(logger.get_child(child) if child else logger)

    def child(self, name: str) -> 'NodeLog':
        """The log of a part, named `<this log's name>.<name>`."""
        return NodeLog(self.logger.get_child(name))

    def debug(self, message: str) -> None:
        self._write(LoggingSeverity.DEBUG, message)

    def info(self, message: str) -> None:
        self._write(LoggingSeverity.INFO, message)

    def warning(self, message: str) -> None:
        self._write(LoggingSeverity.WARN, message)

    def error(self, message: str) -> None:
        self._write(LoggingSeverity.ERROR, message)

    def _write(self, severity: LoggingSeverity, message: str) -> None:
        if _write is None or not isinstance(self.logger, RcutilsLogger):
            self.logger.log(message, severity)  # a stand-in's, or another rclpy's: its own way
            return
        if not self.logger.is_enabled_for(severity):
            return
        caller = sys._getframe(2)  # who called debug(), info(), warning() or error()
        code = caller.f_code
        _write(severity, self.logger.name, message, code.co_name, code.co_filename, caller.f_lineno)


DONE_CALLBACK_FAILED = 'Unhandled exception in done callback'
"""How rclpy's warning begins when a done callback it ran in place raised (a future without an
executor: the node's requests, rclpy_tools.calls)."""


def log_warnings(logger: Any) -> None:
    """Python's warnings as lines of `logger` (an RcutilsLogger: its `error` and `warning`), not
    on stderr only, and every one of rclpy's for a done callback that raised (Python shows a
    warning once per place): as a callback's error was logged when rclpy ran done callbacks as
    tasks."""
    warnings.showwarning = warning_writer(logger)
    warnings.filterwarnings('always', message=DONE_CALLBACK_FAILED)


def warning_writer(logger: Any) -> Callable[..., None]:
    """A `warnings.showwarning` that writes one line of `logger`: an error for a done callback
    that raised, else a warning."""

    def show(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        text = f'{category.__name__}: {message} ({filename}:{lineno})'
        if str(message).startswith(DONE_CALLBACK_FAILED):
            logger.error(text)
        else:
            logger.warning(text)

    return show
