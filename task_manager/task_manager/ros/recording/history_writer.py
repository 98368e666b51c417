"""Writing task changes to the history before they are announced.

Every change is buffered in the TaskHistory; one flush per executor turn commits them all in
one transaction. A task's end is announced (ENDED event, /task_manager/results, the
ExecuteTask result) only after the flush that committed it. A write that fails (disk full)
does not stop anything: tasks keep running and ends keep being announced, the error is
logged at most once a minute, and the buffered changes are written again on the next flush
(a retry is scheduled while nothing else changes).
"""

import os
import sqlite3
import time
from collections.abc import Callable

from rclpy.node import Node
from rclpy.task import Future
from rclpy.timer import Timer

from task_manager.core.errors import ConfigurationError
from task_manager.core.history.store import HistoryError, HistoryInUseError, TaskHistory
from task_manager.core.task import TaskRecord
from task_manager.rclpy_tools.cleanup import destroy_timer
from task_manager.rclpy_tools.log import NodeLog
from task_manager.ros.parking_executor import spawn_after_turn

WRITE_ERROR_LOG_PERIOD_SEC = 60.0
RETRY_AFTER_SEC = 5.0


def open_history(path: str, log: NodeLog) -> TaskHistory:
    """The history at `path`. A file that is not a usable history is moved aside (a robot
    must start) with a warning naming where; a path that cannot be written is a
    ConfigurationError (one line, exit code 2)."""
    try:
        try:
            return TaskHistory(path)
        except HistoryError as error:
            aside = f'{path}.unusable-{time.strftime("%Y%m%d-%H%M%S")}'
            for suffix in ('', '-wal', '-shm'):
                if os.path.exists(path + suffix):
                    os.replace(path + suffix, aside + suffix)
            log.warning(f'{error}: moved it to {aside} and started a new history')
            return TaskHistory(path)
    except (OSError, sqlite3.Error, HistoryInUseError) as error:
        raise ConfigurationError(f'cannot open the task history {path}: {error}') from None


class HistoryWriter:
    """Buffers changes, flushes once per executor turn, then announces the ended tasks."""

    def __init__(
        self,
        node: Node,
        history: TaskHistory,
        announce: Callable[[list[TaskRecord]], None],
    ) -> None:
        self.history = history
        self._node = node
        self._announce = announce
        self._to_announce: list[TaskRecord] = []
        self._flushed: Future[None] | None = None
        self._last_error_logged = -WRITE_ERROR_LOG_PERIOD_SEC
        self._retry: Timer | None = None

    def changed(self, record: TaskRecord) -> None:
        """A task was received or started."""
        self.history.write(record)
        self._flush_soon()

    def ended(self, record: TaskRecord) -> Future[None]:
        """A task ended: it is announced once committed; the future completes after that."""
        record.sequence = self.history.write(record)
        self._to_announce.append(record)
        return self._flush_soon()

    def _flush_soon(self) -> Future[None]:
        if self._flushed is None:
            self._flushed = Future()
            spawn_after_turn(self._node, self._flush())
        return self._flushed

    async def _flush(self) -> None:
        flushed, self._flushed = self._flushed, None
        announce, self._to_announce = self._to_announce, []
        try:
            self.history.flush()
        except sqlite3.Error as error:
            self._write_failed(error)
        if announce:
            self._announce(announce)
        if flushed is not None:
            flushed.set_result(None)

    def _write_failed(self, error: sqlite3.Error) -> None:
        now = time.monotonic()
        if now - self._last_error_logged >= WRITE_ERROR_LOG_PERIOD_SEC:
            self._last_error_logged = now
            NodeLog.of(self._node).error(
                f'cannot write the task history {self.history.path}: {error}; '
                f'{self.history.pending} change(s) kept to write again (logged once a minute)'
            )
        if self._retry is None:
            self._retry = self._node.create_timer(RETRY_AFTER_SEC, self._retry_flush)

    def _retry_flush(self) -> None:
        if self._retry is not None:
            destroy_timer(self._node, self._retry)
            self._retry = None
        self._flush_soon()
