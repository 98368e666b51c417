"""taskctl schedule add|list|remove|enable|disable: tasks and missions started at set times."""

from datetime import datetime
from pathlib import Path
from typing import Any, cast

import typer
from rich.table import Table

from task_manager import ScheduleInfo, TaskResult, scheduled_next_run
from task_manager.cli.common import (
    EXIT_CODES,
    connected,
    on_conflict_option,
    output,
    parse_json_object,
    priority_option,
    progress,
    report_each,
    seconds_option,
    source_option,
    start_option_keywords,
    time_text,
)
from task_manager.cli.durations import parse_span
from task_manager.cli.records import iso, json_line
from task_manager.cli.verbs.mission import load_subtasks
from task_manager.client.schedules import schedule_request
from task_manager.core.names import GET_SCHEDULES_SERVICE

schedule_app = typer.Typer(
    name='schedule',
    help='Start tasks or missions at set times: once, every period, or on a cron expression '
    '(add, list, remove, disable, enable).',
    no_args_is_help=True,
)

WHEN_OPTIONS = ('--at', '--in', '--every', '--cron')
OVERLAP_CHOICES = ('skip', 'buffer_one', 'cancel_other', 'allow_all')


def parse_moment(text: str, option: str) -> datetime:
    """ISO 8601 text as an aware datetime; without a zone, it is this computer's local time."""
    try:
        moment = datetime.fromisoformat(text.strip())
    except ValueError:
        raise typer.BadParameter(
            f'{text!r} is not an ISO 8601 time; use e.g. 2026-11-25T02:00, '
            '2026-11-25T02:00:00+01:00 or 2026-11-25T01:00:00Z',
            param_hint=option,
        ) from None
    return moment if moment.tzinfo is not None else moment.astimezone()


def _span(text: str, option: str) -> float:
    try:
        return parse_span(text).total_seconds()
    except ValueError as error:
        raise typer.BadParameter(str(error), param_hint=option) from error


def _overlap(text: str) -> str:
    if text and text.lower() not in OVERLAP_CHOICES:
        raise typer.BadParameter(
            f'{text!r} is not an overlap policy; use {", ".join(OVERLAP_CHOICES)}',
            param_hint='--overlap',
        )
    return text.upper()


def schedule_options(
    *,
    at: str | None = None,
    delay: str | None = None,
    every: str | None = None,
    cron: str = '',
    time_zone: str = '',
    start: str | None = None,
    end: str | None = None,
    max_runs: int = 0,
    overlap: str = '',
    misfire_grace: str | None = None,
) -> dict[str, Any]:
    """The keyword arguments of schedule_task from taskctl's option texts; BadParameter if
    they do not make a schedule (checked as the client checks them, before connecting)."""
    when = (at, delay, every, cron or None)
    given = [option for option, value in zip(WHEN_OPTIONS, when, strict=True) if value is not None]
    if len(given) != 1:
        got = ' and '.join(given) if given else 'none'
        raise typer.BadParameter(
            f'give exactly one of {", ".join(WHEN_OPTIONS)}; got {got}',
            param_hint='/'.join(given or WHEN_OPTIONS),
        )
    options: dict[str, Any] = {
        'at': None if at is None else parse_moment(at, '--at'),
        'delay': None if delay is None else _span(delay, '--in'),
        'period': None if every is None else _span(every, '--every'),
        'cron': cron,
        'time_zone': time_zone,
        'window_start': None if start is None else parse_moment(start, '--start'),
        'window_end': None if end is None else parse_moment(end, '--end'),
        'max_runs': max_runs,
        'overlap': _overlap(overlap),
        'misfire_grace': None if misfire_grace is None else _span(misfire_grace, '--misfire-grace'),
    }
    try:
        schedule_request('-', None, **options)
    except ValueError as error:
        raise typer.BadParameter(str(error), param_hint=given[0]) from error
    return options


def run_options(
    priority: int | None,
    on_conflict: str | None,
    timeout: float | None,
    queue_timeout: float | None,
    feedback_timeout: float | None,
) -> dict[str, Any]:
    """The options of each run, as schedule_task's keywords (its `timeout_sec` is the wait
    for system/schedule, so a run's own timeout is `task_timeout_sec`)."""
    options = start_option_keywords(priority, on_conflict, timeout, queue_timeout, feedback_timeout)
    options['task_timeout_sec'] = options.pop('timeout_sec')
    return options


def options_text(options: dict[str, Any]) -> str:
    """A schedule's run options in one cell: `priority=2 on_conflict=queue`; '' for none."""
    return ' '.join(
        f'{name}={value:g}' if isinstance(value, float) else f'{name}={value}'
        for name, value in options.items()
    )


def scheduled_line(result: TaskResult) -> str:
    """`<schedule id>  next run <time>` for a schedule made; '' for a refusal."""
    if not result.ok:
        return ''
    next_run = scheduled_next_run(result)
    when = 'no run to come' if next_run is None else f'next run {time_text(next_run)}'
    return f'{result.result.get("schedule_id", "")}  {when}'


def _finish_scheduled(result: TaskResult) -> None:
    """Print the schedule made, or why not (one line on stderr) and exit 1."""
    if result.ok:
        print(scheduled_line(result), flush=True)
        return
    why = result.error_message or str(result.result.get('message') or 'refused')
    progress.print(f'{result.error_code or result.status}: {why}', markup=False, soft_wrap=True)
    raise typer.Exit(EXIT_CODES[result.status])


@schedule_app.command('add')
def add(
    ctx: typer.Context,
    task_name: str | None = typer.Argument(
        None, help='A declared task (none with --mission)', show_default=False
    ),
    task_data: str = typer.Argument('{}', help='Its goal or request as a JSON object'),
    at: str | None = typer.Option(
        None, '--at', help="Once, at this ISO 8601 time (no zone: this computer's local time)"
    ),
    delay: str | None = typer.Option(None, '--in', help='Once, this long from now: 45s, 10m, 2h'),
    every: str | None = typer.Option(None, '--every', help='Every span: 30m, 2h, 1d'),
    cron: str = typer.Option(
        '', '--cron', help="minute hour day-of-month month day-of-week, e.g. '0 2 * * *'"
    ),
    time_zone: str = typer.Option(
        '', '--tz', help='IANA time zone of --cron, e.g. Europe/Paris (default: UTC)'
    ),
    schedule_id: str = typer.Option('', '--id', help='Schedule id; generated when empty'),
    start: str | None = typer.Option(None, '--start', help='No run before this ISO 8601 time'),
    end: str | None = typer.Option(None, '--end', help='No run after this ISO 8601 time'),
    max_runs: int = typer.Option(0, '--max-runs', min=0, help='At most this many runs (0: any)'),
    overlap: str = typer.Option(
        '',
        '--overlap',
        help='A run due while the last one is active: skip (default), buffer_one, '
        'cancel_other or allow_all',
    ),
    misfire_grace: str | None = typer.Option(
        None,
        '--misfire-grace',
        help='A run missed while the Task Manager was down still runs if at most this late '
        '(default: 15m)',
    ),
    mission: Path | None = typer.Option(
        None, '--mission', help='Schedule a mission: a YAML or JSON file as taskctl mission reads'
    ),
    source: str = source_option(),
    priority: int | None = priority_option(),
    on_conflict: str | None = on_conflict_option(),
    timeout: float | None = seconds_option('--timeout', 'The longest a run may run'),
    queue_timeout: float | None = seconds_option('--queue-timeout', 'The longest a run may queue'),
    feedback_timeout: float | None = seconds_option(
        '--feedback-timeout', 'The longest an action may go without feedback'
    ),
) -> None:
    """Schedule a task (or --mission): print its schedule id and next run. Exit 1 if refused.

    Each run is started with --priority, --on-conflict and the timeouts given, as taskctl
    start takes them (default: the task's declaration).
    """
    options = run_options(priority, on_conflict, timeout, queue_timeout, feedback_timeout)
    options |= schedule_options(
        at=at,
        delay=delay,
        every=every,
        cron=cron,
        time_zone=time_zone,
        start=start,
        end=end,
        max_runs=max_runs,
        overlap=overlap,
        misfire_grace=misfire_grace,
    )
    if mission is not None and task_name is None:
        subtasks = load_subtasks(mission)
        with connected(ctx) as client:
            try:
                result = client.schedule_mission(
                    subtasks, schedule_id=schedule_id, source=source, **options
                )
            except ValueError as error:  # refused before it was sent
                raise typer.BadParameter(str(error), param_hint='--mission') from error
            _finish_scheduled(result)
    elif mission is None and task_name is not None:
        data = parse_json_object(task_data, 'task data')
        with connected(ctx) as client:
            result = client.schedule_task(
                task_name, data, schedule_id=schedule_id, source=source, **options
            )
            _finish_scheduled(result)
    else:
        raise typer.BadParameter('give a TASK_NAME or --mission FILE (one of them)')


def schedule_data(info: ScheduleInfo) -> dict[str, Any]:
    """A schedule as `taskctl schedule list --json` prints it: stamps in ISO 8601."""
    return cast(dict[str, Any], info.as_dict(iso))


def schedules_table(schedules: list[ScheduleInfo]) -> Table:
    """One row per schedule: what, when, its next and last run, its counts; its run options
    in a column of their own when one has some."""
    table = Table(title=f'schedules ({len(schedules)})')
    with_options = any(info.options for info in schedules)
    columns = ('id', 'task', 'when', 'next run', 'last run', 'last status')
    option_columns = ['options'] if with_options else []
    for column in (*columns, 'runs/missed/skipped', 'enabled', *option_columns):
        table.add_column(column)
    for info in schedules:
        table.add_row(
            info.schedule_id,
            info.task_name,
            info.description,
            '' if info.next_run is None else time_text(info.next_run),
            '' if info.last_run is None else time_text(info.last_run),
            '' if info.last_status is None else str(info.last_status),
            f'{info.run_count}/{info.missed_count}/{info.skipped_count}',
            'yes' if info.enabled else 'no',
            *([options_text(info.options)] if with_options else []),
        )
    return table


@schedule_app.command('list')
def list_schedules(
    ctx: typer.Context,
    schedule_ids: list[str] | None = typer.Argument(None, help='These schedules (default: all)'),
    as_json: bool = typer.Option(False, '--json', help='One JSON object per schedule and line'),
) -> None:
    """List the schedules with their next and last runs."""
    with connected(ctx, services=[GET_SCHEDULES_SERVICE]) as client:
        schedules = client.schedules(schedule_ids or None)
    if as_json:
        for info in schedules:
            print(json_line(schedule_data(info)), flush=True)
        return
    output.print(schedules_table(schedules))


@schedule_app.command('remove')
def remove(
    ctx: typer.Context,
    schedule_ids: list[str] = typer.Argument(..., help='Ids of the schedules to remove'),
    source: str = source_option(),
) -> None:
    """Remove schedules (system/unschedule); runs already started go on. Exit 1 if one fails."""
    with connected(ctx) as client:
        report_each(client.unschedule(schedule_ids, source=source), 'removed', 'removed')


@schedule_app.command('disable')
def disable(
    ctx: typer.Context,
    schedule_ids: list[str] = typer.Argument(..., help='Ids of the schedules to disable'),
    source: str = source_option(),
) -> None:
    """Disable schedules: no runs until enabled; their state and counts are kept."""
    with connected(ctx) as client:
        result = client.enable_schedules(schedule_ids, False, source=source)
        report_each(result, 'changed', 'disabled')


@schedule_app.command('enable')
def enable(
    ctx: typer.Context,
    schedule_ids: list[str] = typer.Argument(..., help='Ids of the schedules to enable'),
    source: str = source_option(),
) -> None:
    """Enable schedules again, from their next due time after now."""
    with connected(ctx) as client:
        result = client.enable_schedules(schedule_ids, True, source=source)
        report_each(result, 'changed', 'enabled')
