"""Schedules as the Task Manager reports them: `ScheduleInfo`, and the first run of a schedule
just made. Each run of a schedule is an ordinary task with id `<schedule_id>-run-<n>` and
source `schedule:<schedule_id>`."""

from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

from task_manager.client.message_values import datetime_of, datetime_of_json, json_object
from task_manager.client.records import TaskResult
from task_manager.core.schedules.schedule import OverlapPolicy
from task_manager.core.status import TaskStatus

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

    @classmethod
    def from_message(cls, message: Any) -> 'ScheduleInfo':
        """From a task_manager_msgs/msg/Schedule."""
        return cls(
            schedule_id=message.schedule_id,
            task_name=message.task_name,
            task_data=json_object(message.task_data),
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
            last_status=TaskStatus(message.last_status) if message.last_status else None,
            run_count=message.run_count,
            missed_count=message.missed_count,
            skipped_count=message.skipped_count,
        )
