"""The history as CSV: who started what, when, and how it ended; one row per task."""

import csv
import io
import json
from typing import Any

COLUMNS = (
    'sequence',
    'task_id',
    'task_name',
    'source',
    'status',
    'error_code',
    'error_message',
    'mission_id',
    'received',
    'started',
    'ended',
    'duration_sec',
    'paused_sec',
    'result',
)


def history_csv(tasks: list[dict[str, Any]]) -> str:
    """CSV text with a header row, from Task documents; `result` as compact JSON."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator='\n')
    writer.writerow(COLUMNS)
    for task in tasks:
        row = {**task, 'result': json.dumps(task.get('result'), separators=(',', ':'))}
        writer.writerow(['' if row.get(column) is None else row[column] for column in COLUMNS])
    return out.getvalue()
