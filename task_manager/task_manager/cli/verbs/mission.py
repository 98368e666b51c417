"""taskctl mission FILE: run a mission from a YAML or JSON list of subtasks, live."""

import json
from datetime import timedelta
from pathlib import Path
from typing import Any

import typer
import yaml
from rich.live import Live
from rich.table import Table
from rich.text import Text

from task_manager import Subtask, TaskHandle, TaskStatus
from task_manager.cli.common import (
    connected,
    duration_text,
    feedback_text,
    finish,
    on_conflict_option,
    output,
    priority_option,
    progress,
    seconds_option,
    source_option,
    start_option_keywords,
)

FEEDBACK_WIDTH = 48


def load_subtasks(path: Path) -> list[Subtask]:
    """Subtasks from a file holding a list of them, or an object with a `subtasks` list."""
    try:
        content = yaml.safe_load(path.read_text())  # YAML is a superset of JSON
    except (OSError, yaml.YAMLError) as error:
        raise typer.BadParameter(f'cannot read {path}: {error}') from error
    items = content.get('subtasks') if isinstance(content, dict) else content
    if not isinstance(items, list) or not items:
        raise typer.BadParameter(f'{path} must hold a non-empty list of subtasks')
    return [_subtask(index, item) for index, item in enumerate(items)]


def _subtask(index: int, item: Any) -> Subtask:
    if not isinstance(item, dict) or not isinstance(item.get('task_name'), str):
        raise typer.BadParameter(f'subtask {index} needs a task_name, got {item!r}')
    data = item.get('task_data', {})
    return Subtask(
        task_name=item['task_name'],
        task_data=data if isinstance(data, str) else json.dumps(data),
        allow_skipping=bool(item.get('allow_skipping', False)),
        task_id=str(item.get('task_id', '')),
    )


class MissionTable:
    """The live table of a mission: each subtask's status, time and latest feedback.

    A subtask's own events (through its handle) give its status, stamps and feedback; the
    mission's feedback says which were skipped, and the status of any whose events were lost.
    """

    def __init__(self, mission: TaskHandle) -> None:
        self._mission = mission

    def __call__(self) -> Table:
        progress_rows = (self._mission.latest_feedback or {}).get('subtasks') or []
        # key: subtask id, value: its row in the mission's latest feedback
        rows_by_id = {row.get('task_id'): row for row in progress_rows if isinstance(row, dict)}
        table = Table(title=self._title())
        for column in ('#', 'task', 'id', 'status', 'time', 'feedback'):
            table.add_column(column)
        table.columns[-1].max_width = FEEDBACK_WIDTH
        for index, subtask in enumerate(self._mission.subtasks):
            row = rows_by_id.get(subtask.task_id, {})
            status, elapsed, feedback = _progress(subtask, row, self._mission.done())
            table.add_row(
                str(index + 1),
                subtask.task_name,
                subtask.task_id,
                status + (' (skipped)' if row.get('skipped') else ''),
                duration_text(elapsed) if elapsed is not None else '',
                Text(feedback, no_wrap=True, overflow='ellipsis'),
            )
        return table

    def _title(self) -> str:
        state = self._mission.state
        if state is None:
            return f'mission {self._mission.task_id}'
        elapsed = state.elapsed()
        time = f'  {duration_text(elapsed)}' if elapsed is not None else ''
        return f'mission {self._mission.task_id}  {state.status}{time}'


def _progress(
    subtask: TaskHandle, row: dict[str, Any], mission_over: bool
) -> tuple[str, timedelta | None, str]:
    """A subtask's status, how long it ran (or has been running), and its latest feedback."""
    if subtask.done():
        result = subtask.result(0)
        return str(result.status), result.duration, ''
    state = subtask.state
    if state is not None:
        running = state.status is TaskStatus.IN_PROGRESS
        return str(state.status), state.elapsed(), feedback_text(state.feedback) if running else ''
    # not received yet (the mission lists those as RECEIVED), or its events did not reach us
    reported = str(row.get('task_status', ''))
    if reported and reported != 'RECEIVED':
        return reported, None, ''
    return ('not run' if mission_over else 'waiting'), None, ''


def mission(
    ctx: typer.Context,
    path: Path = typer.Argument(..., help='YAML or JSON: a list of subtasks'),
    task_id: str = typer.Option('', '--id', help='Mission id; generated when empty'),
    source: str = source_option(),
    no_wait: bool = typer.Option(False, '--no-wait', help='Print the mission id and exit'),
    priority: int | None = priority_option(),
    on_conflict: str | None = on_conflict_option(),
    timeout: float | None = seconds_option('--timeout', 'The longest the mission may run'),
    queue_timeout: float | None = seconds_option('--queue-timeout', 'The longest it may queue'),
    feedback_timeout: float | None = seconds_option(
        '--feedback-timeout', 'The longest it may go without feedback'
    ),
) -> None:
    """Run system/mission; show each subtask's progress. Exit 0 only when it ends DONE.

    The options are those of the mission as one unit (it queues as one).
    """
    subtasks = load_subtasks(path)
    options = start_option_keywords(priority, on_conflict, timeout, queue_timeout, feedback_timeout)
    with connected(ctx, events=not no_wait) as client:
        handle, _ = client.start_mission(subtasks, task_id=task_id, source=source, **options)
        if no_wait:
            output.print(handle.task_id)
            return
        # redrawn as time passes, and at once on each change of the mission's progress (not
        # a terminal: drawn once, at the end)
        with Live(get_renderable=MissionTable(handle), console=progress) as live:
            for _ in handle.feedback():
                live.refresh()
        finish(handle.result())
