"""A row of the task history: one request as stored, and how big it may be.

A row keeps at most HISTORY_TASK_DATA_MAX_BYTES of the request's task_data and
HISTORY_RESULT_MAX_BYTES of its result: a larger one is kept as `{"omitted_bytes": N}`. Each
row knows its `size` in bytes, so that retention can bound the bytes of the history.
"""

from dataclasses import dataclass, fields

from task_manager.core.admission.decisions import decisions_to_json
from task_manager.core.bounds import HISTORY_RESULT_MAX_BYTES, HISTORY_TASK_DATA_MAX_BYTES
from task_manager.core.task import TaskRecord, pauses_to_json
from task_manager.core.text.json_text import compact_json

TEXT_COLUMNS = (
    'task_id', 'task_name', 'source', 'mission_id', 'task_data', 'status', 'error_code', 'result',
    'pauses', 'decisions',
)  # fmt: skip
ROW_OVERHEAD_BYTES = 100
"""What a row holds besides its text (numbers, SQLite's own bytes), about, in its `size`."""


@dataclass(frozen=True)
class HistoryRow:
    """One request as stored."""

    entry: int
    task_id: str
    task_name: str
    source: str
    mission_id: str
    task_data: str
    status: str
    error_code: str
    result: str | None
    received: float
    started: float | None
    ended: float | None
    sequence: int | None
    paused_sec: float = 0.0
    pauses: str = '[]'
    """JSON list of {"paused", "paused_by", "resumed", "resumed_by"}."""
    priority: int = 0
    attempt: int = 1
    decisions: str = '[]'
    """JSON list of {"at", "decision", "reason"} (core/admission/decisions.py)."""
    size: int = 0
    """Its bytes, about: those of its text and ROW_OVERHEAD_BYTES."""


COLUMNS = tuple(f.name for f in fields(HistoryRow))


def kept_text(text: str, max_bytes: int) -> str:
    """`text` (JSON) as a row keeps it: whole up to `max_bytes` (UTF-8), else a note of its
    size, `{"omitted_bytes": N}`."""
    if len(text) * 4 <= max_bytes:  # no character is more than 4 bytes
        return text
    size = len(text.encode(errors='surrogatepass'))
    return text if size <= max_bytes else compact_json({'omitted_bytes': size})


def row_size(*texts: str | None) -> int:
    """The `size` of a row of these texts."""
    return ROW_OVERHEAD_BYTES + sum(
        len(text.encode(errors='surrogatepass')) for text in texts if text is not None
    )


def row_of(record: TaskRecord, entry: int, sequence: int | None) -> tuple[object, ...]:
    """The values of `record`'s row, in the order of COLUMNS."""
    task_data = kept_text(record.task_data, HISTORY_TASK_DATA_MAX_BYTES)
    status, error_code = str(record.status), str(record.error_code)
    result = (
        kept_text(compact_json(record.result), HISTORY_RESULT_MAX_BYTES)
        if record.is_final
        else None
    )
    pauses, decisions = pauses_to_json(record.pauses), decisions_to_json(record.decisions)
    task_id, task_name, source, mission_id = (
        record.task_id, record.task_name, record.source, record.parent_id
    )  # fmt: skip
    size = row_size(
        task_id, task_name, source, mission_id, task_data, status, error_code, result, pauses,
        decisions,
    )  # fmt: skip
    return (
        entry, task_id, task_name, source, mission_id, task_data, status, error_code, result,
        record.received_at, record.started_at, record.ended_at, sequence, record.paused_sec(),
        pauses, record.priority, record.attempt, decisions, size,
    )  # fmt: skip
