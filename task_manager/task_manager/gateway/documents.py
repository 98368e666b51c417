"""The client's records (TaskState, TaskResult, TaskEvent, ScheduleInfo) as protocol JSON
(models.Task...):
what the web gateway and the MQTT bridge both send. Kept out of `protocol`, which loads no
rclpy and no client.

Built as plain dicts, fast enough for every event of a busy robot; the tests check them
against the JSON Schema files.
"""

import contextlib
import logging
from datetime import UTC, datetime
from functools import cache
from typing import Any

from task_manager.client import (
    ConfirmAnswer,
    Decision,
    ScheduleInfo,
    TaskEvent,
    TaskResult,
    TaskState,
    scheduled_next_run,
)
from task_manager.core.errors import ConfigurationError
from task_manager.core.task_spec import PauseMode, parse_interface_name
from task_manager.messages.goal_schema import task_data_schema
from task_manager.protocol.models import ConfirmTask, DeclaredTask

LOG = logging.getLogger(__name__)


def iso(moment: datetime | None) -> str | None:
    """ISO 8601 in UTC, with a Z (as pydantic writes it too)."""
    return None if moment is None else moment.astimezone(UTC).isoformat().replace('+00:00', 'Z')


def task_json(state: TaskState) -> dict[str, Any]:
    """A Task document."""
    error = state.result.get('error') if state.result else None
    duration = state.elapsed() if state.ended_at else None
    return {
        'task_id': state.task_id,
        'task_name': state.task_name,
        'source': state.source,
        'status': str(state.status),
        'error_code': str(state.error_code),
        'error_message': error if isinstance(error, str) else '',
        'mission_id': state.mission_id,
        'received': iso(state.received_at),
        'started': iso(state.started_at),
        'ended': iso(state.ended_at),
        'duration_sec': None if duration is None else duration.total_seconds(),
        'paused_sec': state.paused_before_end().total_seconds(),
        'feedback': state.feedback,
        'result': state.result if state.is_final else None,
        'sequence': state.sequence,
        'priority': state.priority,
        'queue_position': state.queue_position,
        'attempt': state.attempt,
        'decisions': decisions_json(state.decisions),
    }


def decisions_json(decisions: list[Decision]) -> list[dict[str, Any]]:
    """Decision documents, oldest first (`omitted` > 0 where some were left out)."""
    return [
        {'at': iso(each.at), 'decision': each.decision, 'reason': each.reason,
         'omitted': each.omitted}
        for each in decisions
    ]  # fmt: skip


def result_json(result: TaskResult) -> dict[str, Any]:
    """A Task document of a result (which has no feedback, mission or sequence)."""
    return task_json(
        TaskState(
            task_id=result.task_id,
            task_name=result.task_name,
            status=result.status,
            source=result.source,
            error_code=result.error_code,
            received_at=result.received_at,
            started_at=result.started_at,
            ended_at=result.ended_at,
            result=result.result,
            paused=result.paused,
        )
    )


def event_json(event: TaskEvent) -> dict[str, Any]:
    """A TaskEvent document."""
    return {
        'event': str(event.kind),
        'stamp': iso(event.stamp),
        'task': task_json(event.task),
        'reason': event.reason,
    }


def declared_json(entry: dict[str, Any]) -> dict[str, Any]:
    """A DeclaredTask document of an entry of `TaskManagerClient.declared_tasks()`."""
    known = {name: value for name, value in entry.items() if name in DeclaredTask.model_fields}
    interface = str(entry.get('msg_interface', ''))
    with contextlib.suppress(ConfigurationError):  # then shown as the node has it
        interface = str(parse_interface_name(interface))
    return {
        **known,
        'msg_interface': interface,
        'pause': _pause_mode(entry.get('pause')),
        'goal_schema': _goal_schema(interface),
    }


def _pause_mode(declared: object) -> str:
    """The pause mode as the node reads its declaration (`Restart` is restart); none when
    not declared."""
    text = str(declared or PauseMode.NONE.value).strip().lower()
    return text if text in {mode.value for mode in PauseMode} else PauseMode.NONE.value


@cache
def _goal_schema(msg_interface: str) -> dict[str, Any]:
    """The task_data schema; `{}` (anything) when the interface is not installed here."""
    try:
        return task_data_schema(msg_interface)
    except (ImportError, ConfigurationError, TypeError) as error:
        LOG.warning('no task_data schema for %s: %s', msg_interface, error)
        return {}


def schedule_json(schedule: ScheduleInfo) -> dict[str, Any]:
    """A Schedule document."""
    return schedule.as_dict(iso)


def paused_json(result: TaskResult) -> dict[str, Any]:
    """A Paused document of system/pause's result."""
    return {**_steps(result), 'paused': result.result.get('successful_pauses', [])}


def resumed_json(result: TaskResult) -> dict[str, Any]:
    """A Resumed document of system/resume's result."""
    return {**_steps(result), 'resumed': result.result.get('successful_resumes', [])}


def scheduled_json(result: TaskResult, schedule_id: str) -> dict[str, Any]:
    """A Scheduled document of system/schedule's result (`schedule_id`: the one asked for,
    when the Task Manager names none)."""
    return {
        'scheduled': bool(result.result.get('success', False)),
        'schedule_id': result.result.get('schedule_id', schedule_id),
        'next_run': iso(scheduled_next_run(result)),
        'message': str(result.result.get('message', '')) or _error_of(result),
        'task': result_json(result),
    }


def confirmed_json(answer: ConfirmAnswer, request: ConfirmTask, by: str) -> dict[str, Any]:
    """A Confirmed document of an answer the Task Manager took from `by`."""
    outcome = 'rejected' if request.reject else 'confirmed'
    return {'task_id': answer.task_id, 'outcome': outcome, 'by': by, 'comment': request.comment}


def _steps(result: TaskResult) -> dict[str, Any]:
    """The errors and task of a pause's or resume's answer."""
    errors = result.result.get('errors', [])
    if not errors and result.status != 'DONE':  # refused as a whole (e.g. too many ids)
        errors = [_error_of(result) or f'system task ended {result.status}']
    return {'errors': errors, 'task': result_json(result)}


def _error_of(result: TaskResult) -> str:
    error = result.result.get('error')
    return error if isinstance(error, str) else ''
