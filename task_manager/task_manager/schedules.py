"""The client's schedule values, where they were before `task_manager.client` was a package
(taskctl imports them from here)."""

from task_manager.client.schedules import (
    RUN_SOURCE_PREFIX,
    Moment,
    ScheduleInfo,
    Span,
    When,
    iso_8601,
    schedule_request,
    scheduled_next_run,
)

__all__ = [
    'RUN_SOURCE_PREFIX',
    'Moment',
    'ScheduleInfo',
    'Span',
    'When',
    'iso_8601',
    'schedule_request',
    'scheduled_next_run',
]
