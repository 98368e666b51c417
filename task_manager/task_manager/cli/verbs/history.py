"""taskctl history and taskctl stats: the Task Manager's durable task history."""

from datetime import timedelta

import typer
from rich.table import Table

from task_manager import TaskState
from task_manager.cli.common import connected, duration_text, output
from task_manager.cli.durations import parse_span
from task_manager.cli.records import history_data, json_line
from task_manager.cli.verbs.watch import result_line
from task_manager.client import FINAL_STATUSES
from task_manager.core.names import HISTORY_QUERY_LIMIT_MAX, QUERY_TASK_HISTORY_SERVICE


def _span(text: str, option: str) -> timedelta:
    try:
        return parse_span(text)
    except ValueError as error:
        raise typer.BadParameter(str(error), param_hint=option) from error


def _status(text: str) -> str:
    status = text.upper()
    if status and status not in FINAL_STATUSES:
        allowed = ', '.join(FINAL_STATUSES)
        message = f'{text!r} is not an end status; use {allowed}'
        raise typer.BadParameter(message, param_hint='--status')
    return status


def history_line(state: TaskState, as_json: bool) -> str:
    """Like `taskctl results` prints a result; the JSON adds `mission_id`, `sequence` and
    `pauses`."""
    return json_line(history_data(state)) if as_json else result_line(state.to_result(), False)


def history(
    ctx: typer.Context,
    since: str | None = typer.Option(
        None, '--since', help='Ended within this long before now: 45s, 30m, 2h, 1d'
    ),
    task: str = typer.Option('', '--task', help='Only tasks of this name'),
    status: str = typer.Option(
        '', '--status', help='Only tasks that ended so: DONE, ERROR, CANCELED'
    ),
    source: str = typer.Option('', '--source', help='Only tasks from this source'),
    mission: str = typer.Option('', '--mission', help='Only the subtasks of this mission id'),
    limit: int = typer.Option(
        100, '--limit', min=1, max=HISTORY_QUERY_LIMIT_MAX, help='At most this many tasks'
    ),
    oldest_first: bool = typer.Option(
        False, '--oldest-first', help='By sequence number, oldest first (default: newest first)'
    ),
    as_json: bool = typer.Option(False, '--json', help='One JSON object per task and line'),
) -> None:
    """Print ended tasks from the Task Manager's history (kept across restarts), newest first."""
    span, status = None if since is None else _span(since, '--since'), _status(status)
    with connected(ctx, services=[QUERY_TASK_HISTORY_SERVICE]) as client:
        ended = client.history(
            task,
            status=status,
            source=source,
            mission_id=mission,
            since=span,
            limit=limit,
            oldest_first=oldest_first,
        )
    for state in ended:
        print(history_line(state, as_json), flush=True)


def _seconds(duration: timedelta | None) -> float | None:
    return None if duration is None else duration.total_seconds()


def stats(
    ctx: typer.Context,
    since: str = typer.Option(
        '24h', '--since', help='Tasks that ended within this long before now: 45s, 30m, 2h, 1d'
    ),
    task: str = typer.Option('', '--task', help='Only tasks of this name'),
    source: str = typer.Option('', '--source', help='Only tasks from this source'),
    as_json: bool = typer.Option(False, '--json', help='One JSON object per task name and line'),
) -> None:
    """Per task: how many ended, how many DONE, median and p95 time they ran (of those started)."""
    span = _span(since, '--since')
    with connected(ctx, services=[QUERY_TASK_HISTORY_SERVICE]) as client:
        per_task = client.stats(task, source=source, since=span)
    if as_json:
        for row in per_task:
            data = {
                'task_name': row.task_name,
                'count': row.count,
                'done_count': row.done_count,
                'success_rate': row.success_rate,
                'started_count': row.started_count,
                'median_duration_sec': _seconds(row.median_duration),
                'p95_duration_sec': _seconds(row.p95_duration),
            }
            print(json_line(data), flush=True)
        return
    table = Table(title=f'tasks ended in the last {since}')
    for column in ('task', 'count', 'success %', 'median', 'p95'):
        table.add_column(column, justify='left' if column == 'task' else 'right')
    for row in per_task:
        table.add_row(
            row.task_name,
            str(row.count),
            f'{100 * row.success_rate:.1f}',
            '' if row.median_duration is None else duration_text(row.median_duration),
            '' if row.p95_duration is None else duration_text(row.p95_duration),
        )
    output.print(table)
