"""Schedules: tasks and missions the Task Manager starts at set times, through
system/schedule, system/unschedule, system/enable_schedule and /task_manager/get_schedules.

When a schedule runs is one value, `When`, the same for a task and a mission; the client's
methods (scheduling.py) also take its fields as keywords (`schedule_task('dock', period=3600)`).
"""

import math
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any, TypeAlias, TypedDict, Unpack

from task_manager.client.message_values import datetime_of, datetime_of_json, json_object, json_text
from task_manager.client.records import TaskResult, status_of
from task_manager.core.admission.options import RequestOptions
from task_manager.core.schedules.schedule import OverlapPolicy
from task_manager.core.status import TaskStatus
from task_manager.messages.task_messages import options_of_message

RUN_SOURCE_PREFIX = 'schedule:'
"""The source of a schedule's runs: this and the schedule id."""


def scheduled_next_run(result: TaskResult) -> datetime | None:
    """The first run of the schedule a system/schedule result created; None when none."""
    return datetime_of_json(result.result.get('next_run'))


@dataclass(frozen=True)
class ScheduleInfo:
    """One schedule as /task_manager/get_schedules reports it (msg/Schedule), with datetimes.

    A stamp is None where the message has zero (none, or not yet).
    """

    schedule_id: str
    task_name: str
    """The task each run starts (system/mission for a mission)."""
    task_data: dict[str, Any]
    options: dict[str, Any]
    """The options each run is started with (RequestOptions.to_dict); empty: the declaration's."""
    created_by: str
    """The source of the system/schedule task that created it."""
    description: str
    """When it runs, in words: "every 7200 s", "cron '0 2 * * *' (Europe/Paris)", ..."""
    at: datetime | None
    """The time of a schedule that runs once."""
    period: timedelta | None
    """Of a periodic schedule; None for the others."""
    cron: str
    time_zone: str
    window_start: datetime | None
    window_end: datetime | None
    max_runs: int
    """0: no limit."""
    overlap: OverlapPolicy
    misfire_grace: timedelta
    """A run due while the Task Manager was down runs at its start if at most this late."""
    enabled: bool
    created: datetime | None
    next_run: datetime | None
    """None: no more runs."""
    last_run: datetime | None
    """When the last run started; None before the first."""
    last_task_id: str
    last_status: TaskStatus | None
    """The last run's status (IN_PROGRESS while it runs); None before the first run."""
    run_count: int
    missed_count: int
    """Due times not run: too late (the Task Manager was down), or coalesced into one run."""
    skipped_count: int
    """Due times skipped by the overlap policy."""

    @property
    def run_source(self) -> str:
        """The source of its runs."""
        return f'{RUN_SOURCE_PREFIX}{self.schedule_id}'

    def as_dict(self, stamp: Callable[[datetime | None], str | None]) -> dict[str, Any]:
        """Its fields as JSON values, each stamp written by `stamp` (the Schedule document of
        the gateways, taskctl's JSON lines); durations in seconds, enums as their names."""
        return {
            'schedule_id': self.schedule_id,
            'task_name': self.task_name,
            'task_data': self.task_data,
            'options': self.options,
            'created_by': self.created_by,
            'description': self.description,
            'at': stamp(self.at),
            'period_sec': None if self.period is None else self.period.total_seconds(),
            'cron': self.cron,
            'time_zone': self.time_zone,
            'window_start': stamp(self.window_start),
            'window_end': stamp(self.window_end),
            'max_runs': self.max_runs,
            'overlap': str(self.overlap),
            'misfire_grace_sec': self.misfire_grace.total_seconds(),
            'enabled': self.enabled,
            'created': stamp(self.created),
            'next_run': stamp(self.next_run),
            'last_run': stamp(self.last_run),
            'last_task_id': self.last_task_id,
            'last_status': None if self.last_status is None else str(self.last_status),
            'run_count': self.run_count,
            'missed_count': self.missed_count,
            'skipped_count': self.skipped_count,
        }

    @classmethod
    def from_message(cls, message: Any) -> 'ScheduleInfo':
        """From a task_manager_msgs/msg/Schedule."""
        return cls(
            schedule_id=message.schedule_id,
            task_name=message.task_name,
            task_data=json_object(message.task_data),
            options=options_of_message(message.options).to_dict(),
            created_by=message.created_by,
            description=message.description,
            at=datetime_of(message.at),
            period=timedelta(seconds=message.period_sec) if message.period_sec > 0 else None,
            cron=message.cron,
            time_zone=message.time_zone,
            window_start=datetime_of(message.window_start),
            window_end=datetime_of(message.window_end),
            max_runs=message.max_runs,
            overlap=OverlapPolicy(message.overlap or OverlapPolicy.SKIP),
            misfire_grace=timedelta(seconds=max(message.misfire_grace_sec, 0.0)),
            enabled=message.enabled,
            created=datetime_of(message.created),
            next_run=datetime_of(message.next_run),
            last_run=datetime_of(message.last_run),
            last_task_id=message.last_task_id,
            last_status=status_of(message.last_status, ended=False)
            if message.last_status
            else None,
            run_count=message.run_count,
            missed_count=message.missed_count,
            skipped_count=message.skipped_count,
        )


Moment: TypeAlias = datetime | str
"""A timezone-aware datetime, or ISO 8601 text with its zone (checked by the Task Manager)."""
Span: TypeAlias = timedelta | float
"""A timedelta, or seconds."""


@dataclass(frozen=True)
class When:
    """When a schedule runs; checked when made: ValueError says what is wrong.

    Exactly one of: `at` (once), `delay` (once, this long from now), `period` (every period,
    from `window_start` or one period from now), `cron` (5 fields, in `time_zone`, an IANA
    name; '': UTC). Runs happen only within the window, at most `max_runs` (0: no limit).
    `overlap`: SKIP (''), BUFFER_ONE, CANCEL_OTHER or ALLOW_ALL, what a run due while the
    previous one is active does. `misfire_grace`: how late a run missed while the Task
    Manager was down may still run (None: its default). Datetimes must be timezone-aware.
    """

    at: Moment | None = None
    delay: Span | None = None
    period: Span | None = None
    cron: str = ''
    time_zone: str = ''
    window_start: Moment | None = None
    window_end: Moment | None = None
    max_runs: int = 0
    overlap: str = ''
    misfire_grace: Span | None = None

    def __post_init__(self) -> None:
        self.request_fields()  # a When that exists can be sent

    @property
    def runs_once(self) -> bool:
        """Whether it runs at most once."""
        return self.at is not None or self.delay is not None or self.max_runs == 1

    def request_fields(self) -> dict[str, Any]:
        """Its fields of a ScheduleTask request; ValueError if they make none."""
        when = {
            'at': self.at,
            'delay': self.delay,
            'period': self.period,
            'cron': self.cron or None,
        }
        given = [name for name, value in when.items() if value is not None]
        if len(given) != 1:
            got = ' and '.join(given) if given else 'none'
            raise ValueError(f'give exactly one of at, delay, period, cron; got {got}')
        if self.max_runs < 0:
            raise ValueError(f'max_runs must be 0 (no limit) or more, got {self.max_runs}')
        start, end, grace = self.window_start, self.window_end, self.misfire_grace
        return {
            'at': '' if self.at is None else iso_8601(self.at, 'at'),
            'delay_sec': 0.0 if self.delay is None else _seconds(self.delay, 'delay'),
            'period_sec': 0.0 if self.period is None else _seconds(self.period, 'period'),
            'cron': self.cron.strip(),
            'time_zone': self.time_zone,
            'window_start': '' if start is None else iso_8601(start, 'window_start'),
            'window_end': '' if end is None else iso_8601(end, 'window_end'),
            'max_runs': self.max_runs,
            'overlap': _overlap(self.overlap),
            'misfire_grace_sec': (
                -1.0 if grace is None else _seconds(grace, 'misfire_grace', zero_allowed=True)
            ),
        }


class WhenKeywords(TypedDict, total=False):
    """The fields of When as keywords: `period=3600` stands for `When(period=3600)`."""

    at: Moment | None
    delay: Span | None
    period: Span | None
    cron: str
    time_zone: str
    window_start: Moment | None
    window_end: Moment | None
    max_runs: int
    overlap: str
    misfire_grace: Span | None


def when_of(when: When | None, keywords: WhenKeywords) -> When:
    """`when`, or the When its fields given as keywords make; ValueError for both."""
    if when is None:
        return When(**keywords)
    if keywords:
        given = ', '.join(keywords)
        raise ValueError(f'give a When or its fields as keywords, not both (got when and {given})')
    return when


def iso_8601(moment: Moment, name: str) -> str:
    """`moment` as ISO 8601 with its zone; ValueError for a naive datetime."""
    if isinstance(moment, str):
        return moment.strip()
    if moment.tzinfo is None or moment.utcoffset() is None:
        raise ValueError(
            f'{name} {moment.isoformat()} has no time zone; give an aware datetime, e.g. '
            'datetime(2026, 11, 25, 2, tzinfo=ZoneInfo("Europe/Paris")), or ISO 8601 text '
            'with its zone'
        )
    return moment.isoformat()


def _seconds(span: Span, name: str, *, zero_allowed: bool = False) -> float:
    seconds = span.total_seconds() if isinstance(span, timedelta) else float(span)
    if not math.isfinite(seconds) or seconds < 0 or (seconds == 0 and not zero_allowed):
        least = '0 s or more' if zero_allowed else 'more than 0 s'
        raise ValueError(f'{name} must be {least}, got {seconds:g} s')
    return seconds


def _overlap(text: str) -> str:
    if not text:
        return ''
    try:
        return OverlapPolicy(text.strip().upper()).value
    except ValueError:
        names = ', '.join(OverlapPolicy)
        raise ValueError(
            f"overlap {text!r} is not an overlap policy; use one of {names} ('' is SKIP)"
        ) from None


def schedule_request(
    task_name: str,
    task_data: dict[str, Any] | str | None,
    when: When | None = None,
    *,
    schedule_id: str = '',
    options: RequestOptions | None = None,
    **when_keywords: Unpack[WhenKeywords],
) -> dict[str, Any]:
    """The task data of system/schedule (a ScheduleTask request); ValueError if it is not one.

    `when`, or its fields as keywords, says when (see When); `options`, how each run is
    admitted (None or empty: the declaration's).
    """
    request = {
        'schedule_id': schedule_id,
        'task_name': task_name,
        'task_data': json_text(task_data),
        **when_of(when, when_keywords).request_fields(),
    }
    if options is not None and not options.is_empty:
        # JSON, as the request travels in system/schedule's task data; a `priority` key
        # there sets has_priority
        request['options'] = options.to_dict()
    return request
