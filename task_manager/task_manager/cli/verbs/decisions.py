"""taskctl reprioritize ID... N and taskctl why ID: what decides what runs, and why it did."""

import typer

from task_manager.cli.common import (
    check_priority,
    connected,
    progress,
    report_each,
    source_option,
    time_text,
)
from task_manager.cli.records import decision_data, json_line
from task_manager.client import Decision
from task_manager.core.names import GET_TASK_STATES_SERVICE

DECISION_WIDTH = len('reprioritized')
"""The longest decision's name: the reasons start in one column."""


def reprioritize(
    ctx: typer.Context,
    task_ids: list[str] = typer.Argument(..., help='Ids of the active tasks'),
    priority: int = typer.Argument(
        ...,
        callback=check_priority,
        metavar='PRIORITY',
        help='Their new priority (higher wins); a negative one after --, e.g. -- -5',
    ),
    source: str = source_option(),
) -> None:
    """Give active tasks a new priority (system/reprioritize): one line per id.

    A queued task moves in the queue at once; a running one goes on.

    Exit 0 when every one has it.
    """
    with connected(ctx) as client:  # told before the client closes, as confirm
        report_each(
            client.reprioritize(task_ids, priority, source=source),
            'successful_changes',
            f'priority {priority}',
        )


def decision_line(decision: Decision) -> str:
    """`12:03:00  queued         queued behind drive-1 (priority 5), which holds base`."""
    return f'{time_text(decision.at)}  {decision.decision:<{DECISION_WIDTH}}  {decision.reason}'


def why(
    ctx: typer.Context,
    task_id: str = typer.Argument(..., help='A task id, active or ended'),
    as_json: bool = typer.Option(False, '--json', help='One JSON object per decision and line'),
) -> None:
    """Print every decision taken about a task, and why: one line each, oldest first.

    Why it was queued, refused, pre-empted, timed out, retried or reprioritized.

    Each reason names the other party: "queued behind drive-1 (priority 5), which holds base".
    """
    with connected(ctx, services=[GET_TASK_STATES_SERVICE]) as client:
        decisions = client.why(task_id)
    for decision in decisions:
        print(json_line(decision_data(decision)) if as_json else decision_line(decision))
    if not decisions:
        progress.print(
            f'{task_id}: no decision taken about its resources, priority, timeouts or retries',
            markup=False,
        )
