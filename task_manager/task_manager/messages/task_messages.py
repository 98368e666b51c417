"""The Task Manager's own messages (task_manager_msgs), built from its records and read back.

Every message the node publishes or answers with is built here from core's values (a
TaskRecord while the task is active, a HistoryRow once it is stored, a schedule and its
state), and the requests it reads are turned into core's values here too. Stamps are wall
clock seconds (None: zero, "not yet"); results and feedback are compact JSON (NaN and
infinities become null).
"""

from typing import Any

from builtin_interfaces.msg import Time
from task_manager_msgs.action import Mission
from task_manager_msgs.msg import (
    ActiveTask,
    Schedule,
    SubtaskResult,
    TaskDoneResult,
    TaskOptions,
    TaskState,
)
from task_manager_msgs.srv import QueryTaskHistory

from task_manager.core.admission.decisions import decisions_to_json
from task_manager.core.admission.options import OnConflict, RequestOptions, parse_on_conflict
from task_manager.core.history.rows import HistoryRow
from task_manager.core.history.store import HistoryQuery
from task_manager.core.mission import MissionProgress
from task_manager.core.names import HISTORY_QUERY_LIMIT_DEFAULT, HISTORY_QUERY_LIMIT_MAX
from task_manager.core.schedules.book import ScheduleState
from task_manager.core.schedules.schedule import ScheduleSpec
from task_manager.core.task import TaskRecord, pauses_to_json
from task_manager.messages.json_codec import dict_to_json, message_to_dict

NANOSECONDS = 1_000_000_000
# TaskOptions' timeouts: the same names as RequestOptions' (0 in a message: None, not given)
_TIMEOUTS = ('timeout_sec', 'queue_timeout_sec', 'feedback_timeout_sec')
# Schedule's fields that are a ScheduleSpec's or a ScheduleState's of the same name, as they are
_SPEC_FIELDS = (
    'schedule_id', 'task_name', 'task_data', 'created_by', 'period_sec', 'cron', 'time_zone',
    'max_runs', 'misfire_grace_sec',
)  # fmt: skip
_STATE_FIELDS = (
    'enabled', 'last_task_id', 'last_status', 'run_count', 'missed_count', 'skipped_count',
)  # fmt: skip


def stamp_parts(seconds: float | None) -> tuple[int, int]:
    """A wall-clock time as builtin_interfaces/Time's sec and nanosec; zero for None."""
    if seconds is None:
        return 0, 0
    total_ns = round(seconds * NANOSECONDS)
    return total_ns // NANOSECONDS, total_ns % NANOSECONDS


def stamp(seconds: float | None) -> Time:
    """A wall-clock time as builtin_interfaces/Time; zero for None (not yet)."""
    sec, nanosec = stamp_parts(seconds)
    return Time(sec=sec, nanosec=nanosec)


def seconds_of(time_msg: Time) -> float | None:
    """A stamp in seconds; None for zero (not given)."""
    return time_msg.sec + time_msg.nanosec * 1e-9 if time_msg.sec or time_msg.nanosec else None


def to_json(value: dict[str, Any] | None) -> str:
    """Compact JSON of a result or feedback ('' for None); NaN and infinities become null."""
    return '' if value is None else dict_to_json(value)


def _names(task: TaskRecord | HistoryRow) -> dict[str, str]:
    """The fields that name a task and who asked for it, the same in every message."""
    return {'task_id': task.task_id, 'task_name': task.task_name, 'source': task.source}


def _admitted(task: TaskRecord | HistoryRow) -> dict[str, int]:
    """A TaskState's priority and attempt, the same in a record and its row."""
    return {'priority': task.priority, 'attempt': task.attempt}


def _times(received: float | None, started: float | None, ended: float | None) -> dict[str, Time]:
    """A TaskState's three stamps."""
    return {'received': stamp(received), 'started': stamp(started), 'ended': stamp(ended)}


def task_state_fields(record: TaskRecord) -> dict[str, Any]:
    """An active (or just ended) task's whole state: TaskState's fields by name, its three
    stamps as seconds (None: not yet)."""
    return {
        **_names(record),
        **_admitted(record),
        'received': record.received_at,
        'started': record.started_at,
        'ended': record.ended_at,
        'task_status': str(record.status),
        'error_code': str(record.error_code),
        'mission_id': record.parent_id,
        'feedback': to_json(record.latest_feedback),
        'task_result': to_json(record.result) if record.is_final else '',
        'sequence': record.sequence or 0,
        'paused_sec': record.paused_sec(),
        'pauses': pauses_to_json(record.pauses),
        'queue_position': record.queue_position,
        'decisions': decisions_to_json(record.decisions),
    }


def task_state_of_fields(fields: dict[str, Any]) -> TaskState:
    """The TaskState of `task_state_fields`' values."""
    return TaskState(
        **{
            **fields,
            **_times(fields['received'], fields['started'], fields['ended']),
        }
    )


def task_state_msg(record: TaskRecord) -> TaskState:
    """An active (or just ended) task's whole state."""
    return task_state_of_fields(task_state_fields(record))


def task_state_of_row(row: HistoryRow) -> TaskState:
    """A stored task's state, as its history row keeps it (no feedback, no queue position)."""
    return TaskState(
        **_names(row),
        **_admitted(row),
        **_times(row.received, row.started, row.ended),
        task_status=row.status,
        error_code=row.error_code,
        mission_id=row.mission_id,
        task_result=row.result or '',
        sequence=row.sequence or 0,
        paused_sec=row.paused_sec,
        pauses=row.pauses,
        decisions=row.decisions,
    )


def result_fields(record: TaskRecord) -> dict[str, str]:
    """The fields of ExecuteTask's (and StartTask's) result."""
    return {
        'task_id': record.task_id,
        'task_result': to_json(record.result),
        'task_status': str(record.status),
        'error_code': str(record.error_code),
    }


def result_msg(record: TaskRecord) -> TaskDoneResult:
    """An ended task's message on /task_manager/results."""
    return TaskDoneResult(**result_fields(record), task_name=record.task_name, source=record.source)


def result_msg_of_row(row: HistoryRow) -> TaskDoneResult:
    """A stored task's result, as /task_manager/results carried it."""
    return TaskDoneResult(
        **_names(row),
        task_status=row.status,
        error_code=row.error_code,
        task_result=row.result or '{}',
    )


def active_task_msg(record: TaskRecord) -> ActiveTask:
    """An entry of /task_manager/active_tasks."""
    return ActiveTask(
        task_id=record.task_id,
        task_name=record.task_name,
        task_status=str(record.status),
        source=record.source,
    )


def history_query(request: QueryTaskHistory.Request) -> HistoryQuery:
    """What a /task_manager/query_task_history request asks (at most HISTORY_QUERY_LIMIT_MAX
    rows, HISTORY_QUERY_LIMIT_DEFAULT when it names no limit)."""
    return HistoryQuery(
        task_name=request.task_name,
        status=request.status,
        source=request.source,
        mission_id=request.mission_id,
        ended_after=seconds_of(request.ended_after),
        ended_before=seconds_of(request.ended_before),
        after_sequence=request.after_sequence,
        limit=min(request.limit or HISTORY_QUERY_LIMIT_DEFAULT, HISTORY_QUERY_LIMIT_MAX),
        oldest_first=request.oldest_first,
    )


def options_of_message(message: TaskOptions) -> RequestOptions:
    """The options of a TaskOptions (StartTask's goal, ScheduleTask's request); zero and empty
    fields take the declaration's values, an unknown on_conflict is kept as the error."""
    on_conflict: OnConflict | None = None
    error = ''
    if message.on_conflict.strip():
        try:
            on_conflict = parse_on_conflict(message.on_conflict)
        except ValueError as problem:
            error = str(problem)
    return RequestOptions(
        priority=message.priority if message.has_priority else None,
        on_conflict=on_conflict,
        error=error,
        **{name: getattr(message, name) or None for name in _TIMEOUTS},
    )


def task_options_msg(options: RequestOptions) -> TaskOptions:
    """The TaskOptions of a request's options (None: zero, the declaration's)."""
    return TaskOptions(
        has_priority=options.priority is not None,
        priority=options.priority or 0,
        on_conflict=str(options.on_conflict or ''),
        **{name: float(getattr(options, name) or 0.0) for name in _TIMEOUTS},
    )


def schedule_msg(spec: ScheduleSpec, state: ScheduleState) -> Schedule:
    """A schedule and its state as task_manager_msgs/Schedule."""
    return Schedule(
        **{name: getattr(spec, name) for name in _SPEC_FIELDS},
        **{name: getattr(state, name) for name in _STATE_FIELDS},
        description=spec.describe(),
        overlap=str(spec.overlap),
        at=stamp(spec.at),
        window_start=stamp(spec.start),
        window_end=stamp(spec.end),
        created=stamp(spec.created),
        next_run=stamp(state.next_run if state.enabled else None),
        last_run=stamp(state.last_run),
        options=task_options_msg(RequestOptions.from_dict(spec.options)),
    )


def mission_results(progress: MissionProgress) -> dict[str, Any]:
    """A mission's task_result: a row per subtask (Mission's result, as a dict)."""
    rows = [
        SubtaskResult(
            task_id=r.task_id, task_name=r.task_name, task_status=str(r.status), skipped=r.skipped
        )
        for r in progress.rows
    ]
    return message_to_dict(Mission.Result(mission_results=rows))
