"""taskctl active [--watch] and taskctl results [--follow]."""

import json

import typer
from rich.live import Live
from rich.table import Table

from task_manager import ActiveTaskInfo, TaskResult
from task_manager.cli.common import connected, output


def active_table(tasks: list[ActiveTaskInfo]) -> Table:
    table = Table(title=f'active tasks ({len(tasks)})')
    for column in ('id', 'task', 'status', 'source'):
        table.add_column(column)
    for task in tasks:
        table.add_row(task.task_id, task.task_name, str(task.status), task.source)
    return table


def active(
    ctx: typer.Context,
    watch: bool = typer.Option(False, '--watch', help='Keep the table up to date until Ctrl-C'),
) -> None:
    """Show the tasks in progress."""
    try:
        with connected(ctx) as client:
            tasks = client.active_tasks()
            if not watch:
                output.print(active_table(tasks))
            elif output.is_terminal:
                with Live(active_table(tasks), console=output) as live:
                    for update in client.active_task_updates():
                        live.update(active_table(update))
            else:  # a pipe: one table per change, as it happens
                output.print(active_table(tasks))
                for update in client.active_task_updates():
                    output.print(active_table(update))
                    output.file.flush()
    except KeyboardInterrupt:  # how watching ends, wherever it is
        pass


def result_line(result: TaskResult, as_json: bool) -> str:
    if as_json:
        return json.dumps(
            {
                'task_id': result.task_id,
                'task_name': result.task_name,
                'status': str(result.status),
                'error_code': str(result.error_code),
                'source': result.source,
                'result': result.result,
            },
            ensure_ascii=False,
        )
    error = f' ({result.error_code})' if result.error_code else ''
    return (
        f'{result.status}{error}  {result.task_name}  {result.task_id}  '
        f'from {result.source!r}  {json.dumps(result.result, ensure_ascii=False)}'
    )


def results(
    ctx: typer.Context,
    follow: bool = typer.Option(
        False, '--follow', '-f', help='Then print new results as they come'
    ),
    last: int = typer.Option(20, '--last', help='How many kept results to print first (0: all)'),
    as_json: bool = typer.Option(False, '--json', help='One JSON object per line'),
) -> None:
    """Print the latest task results the Task Manager kept, oldest first."""
    try:
        with connected(ctx) as client:
            for result in client.recent_results(last):
                print(result_line(result, as_json), flush=True)
            if follow:
                for result in client.results():
                    print(result_line(result, as_json), flush=True)
    except KeyboardInterrupt:  # how following ends, wherever it is
        pass
