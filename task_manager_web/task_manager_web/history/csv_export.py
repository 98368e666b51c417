"""The history as CSV: who started what, when, and how it ended; one row per task.

A text cell a spreadsheet would read as a formula (one that begins with `=`, `+`, `-`, `@`, a
tab or a carriage return, as OWASP lists them: a task id `=HYPERLINK(...)` would run when the
file is opened) is written with a single quote before it, which shows it as text.
"""

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
FORMULA_STARTS = ('=', '+', '-', '@', '\t', '\r')


def history_csv(tasks: list[dict[str, Any]]) -> str:
    """CSV text with a header row, from Task documents; `result` as compact JSON."""
    return ''.join(csv_lines(tasks))


def csv_lines(tasks: list[dict[str, Any]], columns: tuple[str, ...] = COLUMNS) -> list[str]:
    """The header line, then one line per task (lines that a cell's line break continues), of
    `columns` (the fleet console's begin with `robot_id`)."""
    out = io.StringIO()
    # CRLF, as RFC 4180 has it: the writer then also quotes a cell holding a lone CR
    writer = csv.writer(out, lineterminator='\r\n')
    rows: list[list[Any]] = [list(columns)]
    for task in tasks:
        cells = {**task, 'result': json.dumps(task.get('result'), separators=(',', ':'))}
        rows.append([_cell(cells.get(column)) for column in columns])
    lines = []
    for row in rows:
        writer.writerow(row)
        lines.append(out.getvalue())
        out.seek(0)
        out.truncate()
    return lines


def _cell(value: Any) -> Any:
    """What is written for `value`: text a spreadsheet would take for a formula, quoted."""
    if value is None:
        return ''
    if isinstance(value, str) and value.startswith(FORMULA_STARTS):
        return f"'{value}"
    return value
