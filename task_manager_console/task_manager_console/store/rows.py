"""A robot's result (its Task document) as a row of the fleet history, and back.

Nothing of a result is trusted: it came from a robot over the broker. A result that cannot be a
row (no positive `sequence`, an id or name that is no text, has control characters or is too
long, a stamp that is no time) is BadResultError, saying why. A row keeps at most
HISTORY_RESULT_MAX_BYTES of the task's result and of the rest of its document: a larger result
is kept as `{"omitted_bytes": N}`, larger decisions as one `omitted` entry.
"""

import json
import math
from datetime import UTC, datetime
from typing import Any

from task_manager.core.bounds import (
    HISTORY_RESULT_MAX_BYTES,
    REASON_MAX_CHARACTERS,
    TEXT_MAX_CHARACTERS,
    cut_text,
)
from task_manager.core.text.request_text import REFUSED, text_problem
from task_manager_console.store.schema import ERROR_CODE_MAX_CHARACTERS, STATUS_MAX_CHARACTERS

Document = dict[str, Any]

TEXT_FIELDS = {
    'task_id': TEXT_MAX_CHARACTERS,
    'task_name': TEXT_MAX_CHARACTERS,
    'source': TEXT_MAX_CHARACTERS,
    'status': STATUS_MAX_CHARACTERS,
    'error_code': ERROR_CODE_MAX_CHARACTERS,
    'mission_id': TEXT_MAX_CHARACTERS,
}
"""The text fields a row has columns for, and the most characters each may have."""
REQUIRED = ('task_id', 'task_name', 'status')
STAMPS = ('received', 'started', 'ended')
DETAILS = ('error_message', 'duration_sec', 'paused_sec', 'priority', 'attempt', 'decisions')
"""What a row keeps of the rest of a Task document (not `feedback`: the task has ended)."""
SEQUENCE_MAX = 2**63 - 1


class BadResultError(ValueError):
    """A result that cannot be stored; the message says why."""


def row_of(robot_id: str, task: object, stored_at: datetime) -> Document:
    """The row of `robot_id`'s result `task` (a Task document), stored at `stored_at` (UTC)."""
    if problem := text_problem('robot_id', robot_id):
        raise BadResultError(problem)
    if not isinstance(task, dict):
        raise BadResultError(f'a result must be a JSON object, got {type(task).__name__}')
    sequence = task.get('sequence')
    if (
        isinstance(sequence, bool)
        or not isinstance(sequence, int)
        or not 0 < sequence <= SEQUENCE_MAX
    ):
        raise BadResultError(f'sequence must be a positive integer, got {cut_text(repr(sequence))}')
    row: Document = {'robot_id': robot_id, 'sequence': sequence}
    for field, limit in TEXT_FIELDS.items():
        row[field] = _text(task, field, limit)
    stamps = {name: _stamp(task, name) for name in STAMPS}
    row.update(
        received=stamps['received'],
        started=stamps['started'],
        ended=stamps['ended'] or stored_at,
        parent_id=row.pop('mission_id'),
        result=_kept_result(task.get('result')),
        details=_details(task),
        stored_at=stored_at,
    )
    return row


def document_of(row: Any) -> Document:
    """The Task document of a row (a mapping of its columns), with `robot_id` and `stored_at`."""
    details = row['details'] or {}
    return {
        'robot_id': row['robot_id'],
        'sequence': row['sequence'],
        'task_id': row['task_id'],
        'task_name': row['task_name'],
        'source': row['source'],
        'status': row['status'],
        'error_code': row['error_code'],
        'mission_id': row['parent_id'],
        **{name: iso(row[name]) for name in STAMPS},
        'result': row['result'],
        **details,
        'stored_at': iso(row['stored_at']),
    }


def utc(stamp: datetime) -> datetime:
    """`stamp` as the database holds it: UTC without a zone (a naive one is taken as UTC)."""
    if stamp.tzinfo is None:
        return stamp
    return stamp.astimezone(UTC).replace(tzinfo=None)


def iso(stamp: datetime | None) -> str | None:
    """A stored (naive UTC) stamp as ISO 8601 text with its zone."""
    return None if stamp is None else stamp.replace(tzinfo=UTC).isoformat()


def _text(task: Document, field: str, limit: int) -> str:
    value = task.get(field, '')
    if value is None and field not in REQUIRED:
        value = ''
    if not isinstance(value, str):
        raise BadResultError(f'{field} must be text, got {type(value).__name__}')
    if field in REQUIRED and not value:
        raise BadResultError(f'{field} is missing')
    if REFUSED.search(value) and (problem := text_problem(field, value)):
        raise BadResultError(problem)
    if len(value) > limit:
        raise BadResultError(f'{field} has {len(value)} characters; at most {limit} are allowed')
    return value


def _stamp(task: Document, field: str) -> datetime | None:
    value = task.get(field)
    if value is None:
        return None
    why = f'{field} must be an ISO 8601 time, got {cut_text(repr(value))}'
    if not isinstance(value, str) or len(value) > 64:
        raise BadResultError(why)
    try:
        return utc(datetime.fromisoformat(value))
    except ValueError:
        raise BadResultError(why) from None


def _kept_result(result: object) -> Any:
    """The result, or `{"omitted_bytes": N}` when its JSON is over HISTORY_RESULT_MAX_BYTES."""
    if result is None:
        return None
    size = _json_size(result)
    return result if size <= HISTORY_RESULT_MAX_BYTES else {'omitted_bytes': size}


def _details(task: Document) -> Document:
    """The rest of the document a row keeps: numbers, the error message (cut to
    REASON_MAX_CHARACTERS) and the decisions (one `omitted` entry if too large)."""
    details: Document = {}
    for name in DETAILS:
        value = task.get(name)
        if name == 'error_message' and isinstance(value, str):
            details[name] = cut_text(value, REASON_MAX_CHARACTERS)
        elif name == 'decisions' and isinstance(value, list):
            size = _json_size(value)
            kept = size <= HISTORY_RESULT_MAX_BYTES
            details[name] = value if kept else [{'decision': 'omitted', 'omitted': len(value)}]
        elif (
            isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        ):
            details[name] = value
    return details


def _json_size(value: object) -> int:
    """Bytes of `value` as compact JSON (UTF-8)."""
    return len(
        json.dumps(value, separators=(',', ':'), ensure_ascii=False).encode(errors='replace')
    )
