"""taskctl mission FILE: run a mission from a YAML or JSON list of subtasks, live."""

import json
from pathlib import Path
from typing import Any

import typer
import yaml
from rich.live import Live
from rich.table import Table

from task_manager import ActiveTaskInfo, Subtask, TaskResult
from task_manager.cli.common import connected, finish, output, progress


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


def _table(subtasks: list[Subtask], ids: list[str], statuses: dict[str, str]) -> Table:
    table = Table(title='mission')
    for column in ('#', 'task', 'id', 'status'):
        table.add_column(column)
    for index, (subtask, task_id) in enumerate(zip(subtasks, ids, strict=True)):
        table.add_row(str(index + 1), subtask.task_name, task_id, statuses.get(task_id, 'waiting'))
    return table


def mission(
    ctx: typer.Context,
    path: Path = typer.Argument(..., help='YAML or JSON: a list of subtasks'),
    task_id: str = typer.Option('', '--id', help='Mission id; generated when empty'),
    source: str = typer.Option('CLI', '--source'),
    no_wait: bool = typer.Option(False, '--no-wait', help='Print the mission id and exit'),
) -> None:
    """Run system/mission; show each subtask's progress. Exit 0 only when it ends DONE."""
    subtasks = load_subtasks(path)
    with connected(ctx) as client:
        handle, ids = client.start_mission(subtasks, task_id=task_id, source=source)
        if no_wait:
            output.print(handle.task_id)
            return
        statuses: dict[str, str] = {}
        with Live(_table(subtasks, ids, statuses), console=progress) as live:
            for update in client.updates(until=handle.result_future):
                _note(update, statuses, ids)
                live.update(_table(subtasks, ids, statuses))
        finish(handle.result())


def _note(
    update: TaskResult | list[ActiveTaskInfo], statuses: dict[str, str], ids: list[str]
) -> None:
    """Subtasks in progress come from active task lists; their ends from results."""
    if isinstance(update, TaskResult):
        if update.task_id in ids:
            statuses[update.task_id] = str(update.status)
        return
    for task in update:
        if task.task_id in ids and statuses.get(task.task_id) in (None, 'RECEIVED'):
            statuses[task.task_id] = str(task.status)
