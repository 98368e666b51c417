"""taskctl cancel ID... and taskctl stop."""

import typer

from task_manager.cli.common import connected, finish, source_option


def cancel(
    ctx: typer.Context,
    task_ids: list[str] = typer.Argument(..., help='Ids of the tasks to cancel'),
    source: str = source_option(),
) -> None:
    """Cancel tasks by id (system/cancel_task). Exit 0 when every cancel succeeded."""
    with connected(ctx) as client:
        finish(client.cancel_tasks(task_ids, source=source))


def stop(ctx: typer.Context, source: str = source_option()) -> None:
    """Cancel every task declared with cancel_on_stop (system/stop)."""
    with connected(ctx) as client:
        finish(client.stop(source=source))
