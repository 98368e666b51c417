"""taskctl pause ID... and taskctl resume ID...: system/pause and system/resume."""

import typer

from task_manager.cli.common import connected, report_each, source_option


def pause(
    ctx: typer.Context,
    task_ids: list[str] = typer.Argument(..., help='Ids of the active tasks to pause'),
    source: str = source_option(),
) -> None:
    """Pause tasks by id (system/pause): one line per id. Exit 0 when every one is paused."""
    with connected(ctx) as client:
        report_each(client.pause(task_ids, source=source), 'successful_pauses', 'paused')


def resume(
    ctx: typer.Context,
    task_ids: list[str] = typer.Argument(..., help='Ids of the paused tasks to resume'),
    source: str = source_option(),
) -> None:
    """Resume paused tasks by id (system/resume): one line per id. Exit 0 when all run again."""
    with connected(ctx) as client:
        report_each(client.resume(task_ids, source=source), 'successful_resumes', 'resumed')
