"""taskctl start NAME [JSON]: start a task and show it until it ends."""

import time
from datetime import timedelta
from typing import cast

import typer
from rich.console import RenderableType
from rich.live import Live
from rich.spinner import Spinner
from rich.text import Text

from task_manager import TaskHandle, TaskManagerClient, TaskManagerError, TaskResult, TaskStatus
from task_manager.cli.common import (
    EXIT_INTERRUPTED,
    connected,
    duration_text,
    feedback_text,
    finish,
    on_conflict_option,
    output,
    parse_json_object,
    priority_option,
    progress,
    seconds_option,
    source_option,
    start_option_keywords,
)
from task_manager.client.records import Decision

LIVE_REFRESH_PER_SEC = 10


def start(
    ctx: typer.Context,
    task_name: str = typer.Argument(..., help='A declared task, e.g. navigation/navigate_to_pose'),
    task_data: str = typer.Argument('{}', help='The goal or request as a JSON object'),
    task_id: str = typer.Option('', '--id', help='Task id; generated when empty'),
    source: str = source_option(),
    no_wait: bool = typer.Option(False, '--no-wait', help='Print the id once started, and exit'),
    priority: int | None = priority_option(),
    on_conflict: str | None = on_conflict_option(),
    timeout: float | None = seconds_option('--timeout', 'The longest it may run'),
    queue_timeout: float | None = seconds_option('--queue-timeout', 'The longest it may queue'),
    feedback_timeout: float | None = seconds_option(
        '--feedback-timeout', 'The longest an action may go without feedback'
    ),
) -> None:
    """Start a task; print its result JSON. Exit 0 only when it ends DONE.

    While it runs, a terminal's stderr shows its status, elapsed time and latest feedback.
    """
    data = parse_json_object(task_data, 'task data')
    options = start_option_keywords(priority, on_conflict, timeout, queue_timeout, feedback_timeout)
    with connected(ctx, events=not no_wait) as client:
        handle = client.start_task(task_name, data, task_id=task_id, source=source, **options)
        if no_wait:
            output.print(handle.task_id)
            return
        result = follow(client, handle)
        finish(result, why_it_ended(client, result))


class LiveLine:
    """The line `taskctl start` keeps up to date: task, status, elapsed time, latest feedback."""

    def __init__(self, handle: TaskHandle) -> None:
        self._handle = handle
        self._started = time.monotonic()
        self._spinner = Spinner('dots')

    def __call__(self) -> RenderableType:
        state = self._handle.state
        elapsed = duration_text(timedelta(seconds=time.monotonic() - self._started))
        parts = [
            f'{self._handle.task_name} {self._handle.task_id}',
            status_text(state.status, state.queue_position) if state is not None else '',
            elapsed,
            feedback_text(self._handle.latest_feedback),
        ]
        line = Text('  '.join(p for p in parts if p), no_wrap=True, overflow='ellipsis')
        self._spinner.update(text=line)
        return self._spinner


def status_text(status: TaskStatus, queue_position: int) -> str:
    """A status, with the place in the queue of a QUEUED task: `QUEUED #2`."""
    if status is TaskStatus.QUEUED and queue_position:
        return f'{status} #{queue_position}'
    return str(status)


def why_it_ended(client: TaskManagerClient, result: TaskResult) -> list[Decision] | None:
    """The decisions of a task that ended without an error of its own (pre-empted, timed
    out: its result is its server's), from the node; None when there is nothing to explain."""
    if result.status is TaskStatus.DONE or result.error_message:
        return None
    try:
        return cast(list[Decision], client.why(result.task_id))
    except TaskManagerError:
        return None


def follow(client: TaskManagerClient, handle: TaskHandle) -> TaskResult:
    """Wait for the task to end, live on stderr when it is a terminal; Ctrl-C cancels it."""
    try:
        if progress.is_terminal:
            with Live(
                get_renderable=LiveLine(handle),
                console=progress,
                transient=True,
                refresh_per_second=LIVE_REFRESH_PER_SEC,
            ) as live:
                for _ in handle.feedback():  # shown at once, not at the next refresh
                    live.refresh()
        return handle.result()
    except KeyboardInterrupt:
        progress.print(f'cancelling {handle.task_id} ...')
        handle.cancel()
        try:
            return handle.result(client.timeout_sec)
        except Exception:
            raise typer.Exit(EXIT_INTERRUPTED) from None
