"""History rows as the Task Manager's messages, and opening the history file safely."""

import os
import sqlite3
import time

from rclpy.impl.rcutils_logger import RcutilsLogger
from task_manager_msgs.msg import TaskDoneResult, TaskState

from task_manager.core.errors import ConfigurationError
from task_manager.core.history import HistoryError, HistoryRow, TaskHistory
from task_manager.ros.task_events import stamp


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
    except (OSError, sqlite3.Error) as error:
        raise ConfigurationError(f'cannot open the task history {path}: {error}') from None
