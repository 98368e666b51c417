"""taskctl tasks: the declared tasks and their properties."""

import typer
from rich.table import Table

from task_manager.cli.common import connected, output
from task_manager.cli.records import DECLARED_FLAGS, declared_data, json_line
from task_manager.core.names import GET_PARAMETERS_SERVICE, LIST_PARAMETERS_SERVICE


def tasks(
    ctx: typer.Context,
    as_json: bool = typer.Option(False, '--json', help='One JSON object per task and line'),
) -> None:
    """List the tasks the Task Manager declares (from its parameters), system tasks included."""
    with connected(ctx, services=[LIST_PARAMETERS_SERVICE, GET_PARAMETERS_SERVICE]) as client:
        declared = [declared_data(entry) for entry in client.declared_tasks()]
    if as_json:
        for task in declared:
            print(json_line(task), flush=True)
        return
    table = Table(title=f'tasks ({len(declared)})')
    for column in ('task', 'interface', 'topic', *DECLARED_FLAGS, 'cancel_timeout'):
        table.add_column(column)
    for task in declared:
        table.add_row(
            task['task_name'],
            task['msg_interface'],
            task['topic'],
            *['yes' if task[name] else '' for name in DECLARED_FLAGS],
            f'{task["cancel_timeout_sec"]:g} s',
        )
    output.print(table)
