"""What the taskctl verbs share: the client, exit codes, output."""

import json
import sys
import threading
from collections.abc import Callable, Collection, Iterator
from contextlib import contextmanager
from datetime import datetime, timedelta
from functools import cache
from typing import Any, Protocol, TypeVar

import typer
from rich.console import Console

from task_manager import TaskManagerClient, TaskManagerUnavailable, TaskResult, TaskStatus
from task_manager.client.records import Decision
from task_manager.core.admission.options import OnConflict
from task_manager.core.bounds import PRIORITY
from task_manager.process_setup import MainThreadInterrupt, end_within, stop_when_unheard

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


def source_option() -> Any:
    """`--source`: who asks, as every verb that sends the Task Manager a request takes it."""
    return typer.Option('CLI', '--source', help='Who asks (the source recorded): CLI, CLOUD, ...')


def check_priority(value: int | None) -> int | None:
    """A priority option or argument: an int32."""
    if value is not None and PRIORITY.problem('priority', value):
        raise typer.BadParameter(f'must be from {PRIORITY.low} to {PRIORITY.high}, got {value}')
    return value


def priority_option() -> Any:
    """`--priority N`: the request's own priority, as every verb that starts a task takes it."""
    return typer.Option(
        None,
        '--priority',
        callback=check_priority,
        metavar='N',
        help='Its priority (higher wins; it pre-empts only tasks of at most its priority); '
        'default: the declared one',
    )


ON_CONFLICT_CHOICES = tuple(mode.value for mode in OnConflict)


def _on_conflict(value: str | None) -> str | None:
    if value is None:
        return None
    if value.strip().lower() not in ON_CONFLICT_CHOICES:
        allowed = ', '.join(ON_CONFLICT_CHOICES)
        raise typer.BadParameter(f'{value!r} is not one of {allowed}')
    return value.strip().lower()


def on_conflict_option() -> Any:
    return typer.Option(
        None,
        '--on-conflict',
        callback=_on_conflict,
        metavar='[' + '|'.join(ON_CONFLICT_CHOICES) + ']',
        help='When its resources are busy: preempt, queue or reject; default: the declared one',
    )


def _positive_seconds(value: float | None) -> float | None:
    if value is not None and not 0 < value < float('inf'):
        raise typer.BadParameter(f'must be a number of seconds > 0, got {value:g}')
    return value


def seconds_option(flag: str, what: str) -> Any:
    """A timeout of the request, in seconds (> 0); default: the declared one."""
    return typer.Option(
        None,
        flag,
        callback=_positive_seconds,
        metavar='SEC',
        help=f'{what}, then it ends ERROR (timeout); default: the declared one',
    )


def start_option_keywords(
    priority: int | None,
    on_conflict: str | None,
    timeout: float | None,
    queue_timeout: float | None,
    feedback_timeout: float | None,
) -> dict[str, Any]:
    """The options of a start, as the client's keywords (None: the declaration's)."""
    return {
        'priority': priority,
        'on_conflict': on_conflict,
        'timeout_sec': timeout,
        'queue_timeout_sec': queue_timeout,
        'feedback_timeout_sec': feedback_timeout,
    }


@contextmanager
def connected(
    ctx: typer.Context, events: bool = False, services: Collection[str] = ()
) -> Iterator[TaskManagerClient]:
    """A client connected to the Task Manager, or TaskManagerUnavailable within the timeout.

    With `events`, also to /task_manager/task_events (when the Task Manager publishes it);
    with `services`, also to these services of it (the verb's: see reach).
    """
    client, unheard = _new_client(ctx.obj['timeout_sec'])
    code = EXIT_ERROR
    try:
        client, unheard = reach(client, unheard, _new_client, events, services)
        yield client
        code = EXIT_DONE
    except typer.Exit as done:
        code = done.exit_code
        raise
    except TaskManagerUnavailable:
        code = EXIT_UNAVAILABLE
        raise
    except KeyboardInterrupt:
        if not unheard.is_set():
            code = EXIT_INTERRUPTED
            raise
        code = EXIT_UNAVAILABLE
        progress.print(
            'taskctl no longer hears the Task Manager (DDS can stay one-sided after a '
            'participant was held up past its lease): run it again'
        )
        raise typer.Exit(code) from None
    finally:
        end_within(client.close, 'taskctl', code)


def _new_client(timeout_sec: float) -> tuple[TaskManagerClient, threading.Event]:
    """A client (a DDS participant of its own) and the event set if it turns deaf to the node
    after a hold-up (Ctrl-Z, a paused machine; its or the node's): the wait in progress then
    ends as Ctrl-C would end it, and taskctl says why (exit 4)."""
    client = TaskManagerClient('taskctl', timeout_sec=timeout_sec)
    return client, stop_when_unheard(client, _main_thread_interrupt())


@cache
def _main_thread_interrupt() -> MainThreadInterrupt:
    """taskctl's one MainThreadInterrupt, made in the main thread (where verbs run)."""
    return MainThreadInterrupt()


class Reaching(Protocol):
    """What reach asks of a client (a TaskManagerClient)."""

    @property
    def timeout_sec(self) -> float: ...

    def wait_until_available(
        self,
        timeout_sec: float | None = None,
        *,
        events: bool = False,
        services: Collection[str] = (),
    ) -> None: ...

    def close(self) -> None: ...


Client = TypeVar('Client', bound=Reaching)


def reach(
    client: Client,
    unheard: threading.Event,
    new_client: Callable[[float], tuple[Client, threading.Event]],
    events: bool,
    services: Collection[str] = (),
) -> tuple[Client, threading.Event]:
    """The client that met the Task Manager (and the `services` the verb calls) within the
    client's timeout: `client`, or, if it did not within half of it, a new one (`new_client`)
    given the other half, while the first may still meet it meanwhile (looked at once more at
    the end); the one not kept is closed.

    A newcomer's participant now and then never matches some of the node's endpoints (its
    action server, a topic, a service) while others started at the same moment match them at
    once: measured here with four taskctls at a time against one node (`taskctl active`),
    6 of 643 waited their whole 15 s in vain (3 of 640 with Fast DDS on UDP alone: not its
    shared memory). A service client made anew in the same participant did not meet its
    service either (2 of 2); a new participant meets the node as the others do.
    """
    timeout_sec = client.timeout_sec
    first_sec = timeout_sec / 2
    try:
        client.wait_until_available(first_sec, events=events, services=services)
        return client, unheard
    except TaskManagerUnavailable:
        first, first_unheard = client, unheard
    try:
        client, unheard = new_client(timeout_sec)
    except BaseException:
        end_within(first.close, 'taskctl', EXIT_UNAVAILABLE)
        raise
    kept, dropped = (client, unheard), first
    try:
        client.wait_until_available(timeout_sec - first_sec, events=events, services=services)
    except TaskManagerUnavailable as error:
        try:  # a first participant merely slow (a loaded machine) may have met it since
            first.wait_until_available(0.0, events=events, services=services)
        except TaskManagerUnavailable:
            end_within(client.close, 'taskctl', EXIT_UNAVAILABLE)
            end_within(first.close, 'taskctl', EXIT_UNAVAILABLE)
            raise TaskManagerUnavailable(
                f'{error} (and {first_sec:g} s before with another DDS participant)'
            ) from None
        kept, dropped = (first, first_unheard), client
    except BaseException:
        end_within(client.close, 'taskctl', EXIT_INTERRUPTED)
        end_within(first.close, 'taskctl', EXIT_INTERRUPTED)
        raise
    end_within(dropped.close, 'taskctl', EXIT_UNAVAILABLE)  # the verb has not run yet
    return kept


def duration_text(duration: timedelta) -> str:
    """`4.2 s`, `3 min 05 s`, `2 h 07 min`."""
    seconds = duration.total_seconds()
    if seconds < 60:
        return f'{seconds:.1f} s'
    minutes, whole_seconds = divmod(int(seconds), 60)
    if minutes < 60:
        return f'{minutes} min {whole_seconds:02d} s'
    hours, minutes = divmod(minutes, 60)
    return f'{hours} h {minutes:02d} min'


def time_text(moment: datetime) -> str:
    """Local time of day, with the date when it is not today."""
    local = moment.astimezone()
    today = datetime.now().astimezone().date()
    return local.strftime('%H:%M:%S' if local.date() == today else '%Y-%m-%d %H:%M:%S')


def _rounded(value: Any) -> Any:
    """`value` with its floats rounded to 3 decimals, for reading at a glance."""
    if isinstance(value, float):
        return round(value, 3)
    if isinstance(value, dict):
        return {key: _rounded(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_rounded(item) for item in value]
    return value


def feedback_text(feedback: dict[str, Any] | None) -> str:
    """A feedback as one line of JSON (floats rounded); '' for none."""
    return '' if feedback is None else json.dumps(_rounded(feedback), ensure_ascii=False)


def parse_json_object(text: str, what: str) -> dict[str, Any]:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as error:
        raise typer.BadParameter(f'{what} is not valid JSON: {error}') from error
    if not isinstance(value, dict):
        raise typer.BadParameter(f'{what} must be a JSON object, got {text!r}')
    return value


def result_json(result: TaskResult) -> str:
    """The result as taskctl prints it (the same fields since the first release)."""
    data = {
        'task_id': result.task_id,
        'task_name': result.task_name,
        'status': str(result.status),
        'error_code': str(result.error_code),
        'result': result.result,
        'source': result.source,
    }
    return json.dumps(data, indent=2, ensure_ascii=False)


# the decisions that end a task (docs/deciding-what-runs.md): why it ended, for stderr
_ENDING_DECISIONS = ('preempted', 'timeout')


def finish(result: TaskResult, decisions: list[Decision] | None = None) -> None:
    """Print a task's result as JSON (and on stderr why it failed, or, from its `decisions`,
    why the Task Manager ended it: pre-empted, timed out); exit with its status' code."""
    output.print_json(result_json(result))
    why = result.error_message
    if not why and decisions and decisions[-1].decision in _ENDING_DECISIONS:
        why = decisions[-1].reason
    if why:
        what = result.error_code or result.status
        progress.print(f'{what}: {why}', markup=False, soft_wrap=True)
    raise typer.Exit(EXIT_CODES[result.status])


def report_each(result: TaskResult, done_field: str, done_word: str) -> None:
    """Print `<id>  <done_word>` for each id a system task did, and on stderr each of its
    errors as `<status>: <error>`; exit with its status' code unless it ended DONE."""
    for done_id in result.result.get(done_field) or []:
        print(f'{done_id}  {done_word}', flush=True)
    errors = [str(line) for line in result.result.get('errors') or []]
    if result.error_message:  # refused before it ran: no per-id lines
        errors.append(result.error_message)
    elif not result.ok and not errors:
        errors.append(str(result.result.get('message') or f'{result.task_name} failed'))
    what = result.error_code or result.status
    for line in errors:
        progress.print(f'{what}: {line}', markup=False, soft_wrap=True)
    if not result.ok:
        raise typer.Exit(EXIT_CODES[result.status])
