"""taskctl confirm ID [--reject] [--comment TEXT]: answer a waiting system/confirm."""

import typer

from task_manager.cli.common import EXIT_ERROR, connected, progress, source_option
from task_manager.core.names import CONFIRM_TASK_SERVICE


def confirm(
    ctx: typer.Context,
    task_id: str = typer.Argument(..., help='Id of the waiting system/confirm task'),
    reject: bool = typer.Option(False, '--reject', help='Reject it (it ends ERROR, rejected)'),
    comment: str = typer.Option('', '--comment', help='Why, kept in its result'),
    source: str = source_option(),
) -> None:
    """Confirm (or --reject) a waiting system/confirm; its result names --source as `by`.

    Prints `ID  confirmed` (or `rejected`); exit 1 with why on stderr when it takes no answer.
    """
    with connected(ctx, services=[CONFIRM_TASK_SERVICE]) as client:
        answer = client.confirm(task_id, reject=reject, comment=comment, source=source)
        # told before the client closes, as every verb that changes something: the answer
        # stands whatever the middleware's teardown does
        if not answer.taken:
            progress.print(f'{answer.error_code}: {answer.message}', markup=False, soft_wrap=True)
            raise typer.Exit(EXIT_ERROR)
        print(f'{task_id}  {"rejected" if reject else "confirmed"}', flush=True)
