"""History rows as the Task Manager's messages, and opening the history file safely."""

import os
import sqlite3
import time

from builtin_interfaces.msg import Time
from rclpy.impl.rcutils_logger import RcutilsLogger
from task_manager_msgs.msg import TaskDoneResult, TaskState
from task_manager_msgs.srv import QueryTaskHistory

from task_manager.core.errors import ConfigurationError
from task_manager.core.history.rows import HistoryRow
from task_manager.core.history.store import (
    HistoryError,
    HistoryInUseError,
    HistoryQuery,
    TaskHistory,
)
from task_manager.core.names import HISTORY_QUERY_LIMIT_DEFAULT as DEFAULT_QUERY_LIMIT
from task_manager.core.names import HISTORY_QUERY_LIMIT_MAX as MAX_QUERY_LIMIT
from task_manager.ros.recording.task_events import stamp


def done_result_msg(row: HistoryRow) -> TaskDoneResult:
    return TaskDoneResult(
        task_id=row.task_id,
        task_name=row.task_name,
        task_status=row.status,
        error_code=row.error_code,
        source=row.source,
        task_result=row.result or '{}',
    )


def task_state_from_row(row: HistoryRow) -> TaskState:
    return TaskState(
        task_id=row.task_id,
        task_name=row.task_name,
        source=row.source,
        task_status=row.status,
        error_code=row.error_code,
        mission_id=row.mission_id,
        received=stamp(row.received),
        started=stamp(row.started),
        ended=stamp(row.ended),
        task_result=row.result or '',
        sequence=row.sequence or 0,
        paused_sec=row.paused_sec,
        pauses=row.pauses,
        priority=row.priority,
        attempt=row.attempt,
        decisions=row.decisions,
    )


# The most tasks one query returns, however many it asks for (a response must stay small).


def _seconds(time_msg: Time) -> float | None:
    """A stamp in seconds; None for zero (no filter)."""
    return time_msg.sec + time_msg.nanosec * 1e-9 if time_msg.sec or time_msg.nanosec else None


def history_query(request: QueryTaskHistory.Request) -> HistoryQuery:
    return HistoryQuery(
        task_name=request.task_name,
        status=request.status,
        source=request.source,
        mission_id=request.mission_id,
        ended_after=_seconds(request.ended_after),
        ended_before=_seconds(request.ended_before),
        after_sequence=request.after_sequence,
        limit=min(request.limit or DEFAULT_QUERY_LIMIT, MAX_QUERY_LIMIT),
        oldest_first=request.oldest_first,
    )


def open_history(path: str, logger: RcutilsLogger) -> TaskHistory:
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
            logger.warning(f'{error}: moved it to {aside} and started a new history')
            return TaskHistory(path)
    except (OSError, sqlite3.Error, HistoryInUseError) as error:
        raise ConfigurationError(f'cannot open the task history {path}: {error}') from None
