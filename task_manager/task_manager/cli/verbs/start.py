"""taskctl start NAME [JSON]: start a task and show it until it ends."""

import time

import typer

from task_manager import TaskHandle, TaskManagerClient
from task_manager.cli.common import (
    EXIT_INTERRUPTED,
    connected,
    finish,
    output,
    parse_json_object,
    progress,
)


def start(
    ctx: typer.Context,
    task_name: str = typer.Argument(..., help='A declared task, e.g. navigation/navigate_to_pose'),
    task_data: str = typer.Argument('{}', help='The goal or request as a JSON object'),
    task_id: str = typer.Option('', '--id', help='Task id; generated when empty'),
    source: str = typer.Option('CLI', '--source', help='Who asks: CLI, CLOUD, ...'),
    no_wait: bool = typer.Option(False, '--no-wait', help='Print the id once started, and exit'),
) -> None:
    """Start a task; print its result JSON. Exit 0 only when it ends DONE."""
    data = parse_json_object(task_data, 'task data')
    with connected(ctx) as client:
        handle = client.start_task(task_name, data, task_id=task_id, source=source)
        if no_wait:
            output.print(handle.task_id)
            return
        finish(follow(client, handle))


def follow(client: TaskManagerClient, handle: TaskHandle) -> object:
    """Show the task's status until it ends; Ctrl-C cancels it."""
    started = time.monotonic()
    try:
        with progress.status(f'{handle.task_name} {handle.task_id}: starting') as status:
            for tasks in client.active_task_updates(until=handle.result_future):
                state = next((t.status for t in tasks if t.task_id == handle.task_id), None)
                if state is not None:
                    elapsed = time.monotonic() - started
                    status.update(f'{handle.task_name} {handle.task_id}: {state} ({elapsed:.1f} s)')
        return handle.result()
    except KeyboardInterrupt:
        progress.print(f'cancelling {handle.task_id} ...')
        handle.cancel()
        try:
            return handle.result(client.timeout_sec)
        except Exception:
            raise typer.Exit(EXIT_INTERRUPTED) from None
