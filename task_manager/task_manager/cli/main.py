"""The taskctl application: verbs, global options, and errors as one line and an exit code."""

import sys

import typer

from task_manager import TaskManagerError, TaskManagerUnavailable
from task_manager.cli.common import EXIT_ERROR, EXIT_INTERRUPTED, EXIT_UNAVAILABLE, progress
from task_manager.cli.verbs.cancel import cancel, stop
from task_manager.cli.verbs.confirm import confirm
from task_manager.cli.verbs.decisions import reprioritize, why
from task_manager.cli.verbs.history import history, stats
from task_manager.cli.verbs.mission import mission
from task_manager.cli.verbs.pause import pause, resume
from task_manager.cli.verbs.schedule import schedule_app
from task_manager.cli.verbs.start import start
from task_manager.cli.verbs.tasks import tasks
from task_manager.cli.verbs.watch import active, results
from task_manager.core.bounds import SECONDS
from task_manager.process_setup import prepare_ros_process

app = typer.Typer(
    name='taskctl',
    help='Start, watch, pause, confirm, cancel, reprioritize and schedule the tasks of a running '
    'ROS 2 Task Manager.',
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _client_seconds(value: float) -> float:
    if problem := SECONDS.problem('--timeout', value):
        raise typer.BadParameter(problem)
    return value


@app.callback()
def options(
    ctx: typer.Context,
    timeout: float = typer.Option(
        5.0,
        '--timeout',
        callback=_client_seconds,
        help='Seconds to wait for the Task Manager to answer',
    ),
) -> None:
    ctx.obj = {'timeout_sec': timeout}


VERBS = (start, mission, cancel, stop, pause, resume, confirm, reprioritize, why, active, results,
         history, stats, tasks)  # fmt: skip
for verb in VERBS:
    app.command()(verb)
app.add_typer(schedule_app)


def main() -> None:
    """Run taskctl; errors print one `ErrorType: message` line and exit non-zero."""
    prepare_ros_process()
    try:
        app()  # exits by itself, also for usage errors (exit code 2)
    except TaskManagerUnavailable as error:
        progress.print(f'TaskManagerUnavailable: {error}', markup=False, soft_wrap=True)
        sys.exit(EXIT_UNAVAILABLE)
    except TaskManagerError as error:
        progress.print(f'{type(error).__name__}: {error}', markup=False, soft_wrap=True)
        sys.exit(EXIT_ERROR)
    except KeyboardInterrupt:
        sys.exit(EXIT_INTERRUPTED)
