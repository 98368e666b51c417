"""taskctl active [--watch] and taskctl results [--follow]."""

import json
from collections.abc import Iterator, Sequence
from dataclasses import replace
from datetime import datetime
from typing import Any, TypeAlias

import typer
from rich.live import Live
from rich.table import Table
from rich.text import Text

from task_manager import (
    ActiveTaskInfo,
    TaskEventKind,
    TaskManagerClient,
    TaskResult,
    TaskState,
    TaskStatus,
)
from task_manager.cli.common import connected, duration_text, output, time_text

ActiveRow: TypeAlias = ActiveTaskInfo | TaskState


def active_table(tasks: Sequence[ActiveRow]) -> Table:
    """The active tasks; `running for` needs their stamps (TaskState rows), and stops while
    a task is PAUSED."""
    table = Table(title=f'active tasks ({len(tasks)})')
    for column in ('id', 'task', 'status', 'source', 'running for'):
        table.add_column(column)
    for task in tasks:
        elapsed = task.elapsed() if isinstance(task, TaskState) else None
        table.add_row(
            task.task_id,
            task.task_name,
            Text(str(task.status), style='yellow' if task.status is TaskStatus.PAUSED else ''),
            task.source,
            duration_text(elapsed) if elapsed is not None else '',
        )
    return table


class StampedActiveTasks:
    """The active tasks with their stamps, kept up to date from /task_manager/active_tasks.

    First every active task from /task_manager/get_task_states (the latest list on the
    topic may reach a new subscriber after older ones); then the topic's lists, with the
    stamps of each task asked for once, and again when its status changes (a start, a pause
    or resume, its end).
    """

    def __init__(self, client: TaskManagerClient) -> None:
        self._client = client
        self.rows: list[ActiveRow] = list(client.task_states())
        # key: task id, value: its state when last asked
        self._states: dict[str, TaskState] = {s.task_id: s for s in self.rows}

    def update(self, tasks: list[ActiveTaskInfo]) -> list[ActiveRow]:
        stale = [
            t.task_id
            for t in tasks
            if t.task_id not in self._states or t.status is not self._states[t.task_id].status
        ]
        if stale:
            self._states.update((s.task_id, s) for s in self._client.task_states(stale))
        known = {t.task_id for t in tasks}
        self._states = {i: s for i, s in self._states.items() if i in known}
        self.rows = [
            replace(self._states[t.task_id], status=t.status) if t.task_id in self._states else t
            for t in tasks
        ]
        return self.rows


def active(
    ctx: typer.Context,
    watch: bool = typer.Option(False, '--watch', help='Keep the table up to date until Ctrl-C'),
) -> None:
    """Show the tasks in progress."""
    try:
        with connected(ctx) as client:
            tasks = StampedActiveTasks(client)
            if not watch:
                output.print(active_table(tasks.rows))
            elif output.is_terminal:  # redrawn as time passes, too
                with Live(get_renderable=lambda: active_table(tasks.rows), console=output) as live:
                    for update in client.active_task_updates():
                        tasks.update(update)
                        live.refresh()
            else:  # a pipe: one table per change, as it happens
                output.print(active_table(tasks.rows))
                for update in client.active_task_updates():
                    output.print(active_table(tasks.update(update)))
                    output.file.flush()
    except KeyboardInterrupt:  # how watching ends, wherever it is
        pass


def _iso(moment: datetime | None) -> str | None:
    return None if moment is None else moment.isoformat()


def result_data(result: TaskResult) -> dict[str, Any]:
    """A result's fields as `--json` prints them: stamps in ISO 8601, `duration_sec`."""
    duration = result.duration
    return {
        'task_id': result.task_id,
        'task_name': result.task_name,
        'status': str(result.status),
        'error_code': str(result.error_code),
        'source': result.source,
        'result': result.result,
        'received_at': _iso(result.received_at),
        'started_at': _iso(result.started_at),
        'ended_at': _iso(result.ended_at),
        'duration_sec': None if duration is None else duration.total_seconds(),
        'paused_sec': result.paused.total_seconds(),
    }


def result_line(result: TaskResult, as_json: bool) -> str:
    duration = result.duration
    if as_json:
        return json.dumps(result_data(result), ensure_ascii=False)
    error = f' ({result.error_code})' if result.error_code else ''
    when = ''
    if result.ended_at is not None:
        took = f' after {duration_text(duration)}' if duration is not None else ', never started'
        when = f'  ended {time_text(result.ended_at)}{took}'
    return (
        f'{result.status}{error}  {result.task_name}  {result.task_id}  '
        f'from {result.source!r}{when}  {json.dumps(result.result, ensure_ascii=False)}'
    )


def new_results(client: TaskManagerClient) -> Iterator[TaskResult]:
    """Results as tasks end: from ENDED events (with stamps) when they reach us, else plain."""
    if not client.events_connected:
        yield from client.results()
        return
    for event in client.task_events():
        if event.kind is TaskEventKind.ENDED:
            yield event.task.to_result()


def results(
    ctx: typer.Context,
    follow: bool = typer.Option(
        False, '--follow', '-f', help='Then print new results as they come'
    ),
    last: int = typer.Option(20, '--last', help='How many kept results to print first (0: all)'),
    as_json: bool = typer.Option(False, '--json', help='One JSON object per line'),
) -> None:
    """Print the latest task results the Task Manager kept, oldest first: when each ended."""
    try:
        with connected(ctx, events=follow) as client:
            for result in client.recent_results(last):
                print(result_line(result, as_json), flush=True)
            if follow:
                for result in new_results(client):
                    print(result_line(result, as_json), flush=True)
    except KeyboardInterrupt:  # how following ends, wherever it is
        pass
