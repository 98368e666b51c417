"""What the taskctl verbs share: the client, exit codes, output."""

import json
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict
from typing import Any

import typer
from rich.console import Console

from task_manager import TaskManagerClient, TaskResult, TaskStatus

EXIT_DONE = 0
EXIT_ERROR = 1
EXIT_CANCELED = 3
EXIT_UNAVAILABLE = 4
EXIT_INTERRUPTED = 130
# key: a task's end status, value: taskctl's exit code for it
EXIT_CODES = {
    TaskStatus.DONE: EXIT_DONE,
    TaskStatus.ERROR: EXIT_ERROR,
    TaskStatus.CANCELED: EXIT_CANCELED,
}

PIPE_WIDTH = 200
output = Console(width=None if sys.stdout.isatty() else PIPE_WIDTH)
"""Results and tables: stdout. Piped output is not wrapped at 80 columns."""
progress = Console(stderr=True)
"""Spinners and notes: stderr."""


@contextmanager
def connected(ctx: typer.Context) -> Iterator[TaskManagerClient]:
    """A client connected to the Task Manager, or TaskManagerUnavailable within the timeout."""
    with TaskManagerClient('taskctl', timeout_sec=ctx.obj['timeout_sec']) as client:
        client.wait_until_available()
        yield client


def parse_json_object(text: str, what: str) -> dict[str, Any]:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as error:
        raise typer.BadParameter(f'{what} is not valid JSON: {error}') from error
    if not isinstance(value, dict):
        raise typer.BadParameter(f'{what} must be a JSON object, got {text!r}')
    return value


def result_json(result: TaskResult) -> str:
    data = asdict(result)
    data['status'], data['error_code'] = str(result.status), str(result.error_code)
    return json.dumps(data, indent=2, ensure_ascii=False)


def finish(result: TaskResult) -> None:
    """Print a task's result as JSON (and why it failed on stderr); exit with its status' code."""
    output.print_json(result_json(result))
    if result.error_message:
        what = result.error_code or result.status
        progress.print(f'{what}: {result.error_message}', markup=False, soft_wrap=True)
    raise typer.Exit(EXIT_CODES[result.status])
