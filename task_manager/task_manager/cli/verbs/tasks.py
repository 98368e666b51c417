"""taskctl tasks: the declared tasks and their properties."""

import typer
from rich.table import Table

from task_manager.cli.common import connected, output

PROPERTIES = ('blocking', 'cancel_on_stop', 'reentrant', 'cancel_reported_as_success')


def tasks(ctx: typer.Context) -> None:
    """List the tasks the Task Manager declares (from its parameters), system tasks included."""
    with connected(ctx) as client:
        declared = client.declared_tasks()
    table = Table(title=f'tasks ({len(declared)})')
    for column in ('task', 'interface', 'topic', *PROPERTIES, 'cancel_timeout'):
        table.add_column(column)
    for task in declared:
        flags = ['yes' if task.get(name) else '' for name in PROPERTIES]
        table.add_row(
            task.get('task_name', ''),
            task.get('msg_interface', ''),
            task.get('topic', ''),
            *flags,
            f'{float(task.get("cancel_timeout", 5.0)):g} s',
        )
    output.print(table)
