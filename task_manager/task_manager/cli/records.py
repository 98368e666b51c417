"""What taskctl's `--json` prints: one JSON object per line, of the shapes below.

The shapes are documented in docs/taskctl.md. Times are ISO 8601 with their zone, spans of
time are seconds in fields named `..._sec`; a field that is not known is `null`.
"""

import json
from collections.abc import Sequence
from datetime import datetime
from typing import Any

from task_manager import ActiveTaskInfo, Pause, TaskResult, TaskState
from task_manager.client import Decision
from task_manager.client.records import paused_time
from task_manager.core.names import CONFIRM

# key: a property of a declared task in taskctl's JSON, value: its default
DECLARED_FLAGS = {
    'blocking': False,
    'cancel_on_stop': False,
    'reentrant': False,
    'cancel_reported_as_success': False,
}
DEFAULT_CANCEL_TIMEOUT_SEC = 5.0


def json_line(data: Any) -> str:
    return json.dumps(data, ensure_ascii=False)


def iso(moment: datetime | None) -> str | None:
    return None if moment is None else moment.isoformat()


def result_data(result: TaskResult) -> dict[str, Any]:
    """A result (`taskctl results`): stamps in ISO 8601, `duration_sec` (the time it ran)."""
    duration = result.duration
    return {
        'task_id': result.task_id,
        'task_name': result.task_name,
        'status': str(result.status),
        'error_code': str(result.error_code),
        'source': result.source,
        'result': result.result,
        'received_at': iso(result.received_at),
        'started_at': iso(result.started_at),
        'ended_at': iso(result.ended_at),
        'duration_sec': None if duration is None else duration.total_seconds(),
        'paused_sec': result.paused.total_seconds(),
    }


def pauses_data(pauses: Sequence[Pause]) -> list[dict[str, Any]]:
    """Each pause of a task, oldest first; `resumed_at` is null while it lasts."""
    return [
        {
            'paused_at': iso(pause.paused_at),
            'paused_by': pause.paused_by,
            'resumed_at': iso(pause.resumed_at),
            'resumed_by': pause.resumed_by,
        }
        for pause in pauses
    ]


def history_data(state: TaskState) -> dict[str, Any]:
    """An ended task from the history (`taskctl history`): a result with `mission_id`,
    `sequence` and `pauses`."""
    return {
        **result_data(state.to_result()),
        'mission_id': state.mission_id,
        'sequence': state.sequence,
        'pauses': pauses_data(state.pauses),
    }


def decision_data(decision: Decision) -> dict[str, Any]:
    """One decision the Task Manager took about a task (`taskctl why`)."""
    return {'at': iso(decision.at), 'decision': decision.decision, 'reason': decision.reason}


def active_data(task: ActiveTaskInfo | TaskState, now: datetime) -> dict[str, Any]:
    """An active task (`taskctl active`) at `now`: `duration_sec` is how long it has run so far
    (the clock stops while it is paused); `queue_position` is 0 unless it is QUEUED. Without
    its state (stamps, priority, place in the queue), those are null."""
    known = isinstance(task, TaskState)
    state = (
        task
        if isinstance(task, TaskState)
        else TaskState(task.task_id, task.task_name, task.status, task.source)
    )
    elapsed = state.elapsed(now)
    return {
        'task_id': state.task_id,
        'task_name': state.task_name,
        'status': str(state.status),
        'source': state.source,
        'mission_id': state.mission_id,
        'received_at': iso(state.received_at),
        'started_at': iso(state.started_at),
        'duration_sec': None if elapsed is None else elapsed.total_seconds(),
        'paused_sec': paused_time(state.pauses, state.paused, now).total_seconds(),
        'pauses': pauses_data(state.pauses),
        'priority': state.priority if known else None,
        'queue_position': state.queue_position if known else None,
        'attempt': state.attempt if known else None,
        'prompt': prompt_of(task),
    }


def prompt_of(task: ActiveTaskInfo | TaskState) -> str:
    """What a waiting system/confirm asks (its feedback's prompt); '' for any other task."""
    feedback = task.feedback if isinstance(task, TaskState) else None
    prompt = (feedback or {}).get('prompt') if task.task_name == CONFIRM else None
    return prompt if isinstance(prompt, str) else ''


def declared_data(entry: dict[str, Any]) -> dict[str, Any]:
    """A declared task (`taskctl tasks`), from an entry of the client's `declared_tasks()`."""
    return {
        'task_name': entry.get('task_name', ''),
        'msg_interface': entry.get('msg_interface', ''),
        'topic': entry.get('topic', ''),
        **{name: bool(entry.get(name, default)) for name, default in DECLARED_FLAGS.items()},
        'cancel_timeout_sec': float(entry.get('cancel_timeout', DEFAULT_CANCEL_TIMEOUT_SEC)),
    }
