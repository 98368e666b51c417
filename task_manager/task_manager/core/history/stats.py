"""Per-task statistics over ended tasks: how many, how often DONE, how long they ran (time
paused excluded).

Pure: computed from any records with a task name, a status and stamps (the client's
`TaskState`s from the history), so it is tested without ROS.
"""

import math
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Protocol

from task_manager.core.status import TaskStatus


class EndedTask(Protocol):
    """What the statistics read of one ended task."""

    @property
    def task_name(self) -> str: ...

    @property
    def status(self) -> TaskStatus: ...

    @property
    def started_at(self) -> datetime | None: ...

    @property
    def ended_at(self) -> datetime | None: ...

    @property
    def paused(self) -> timedelta:
        """Time spent paused: not running time."""
        ...


@dataclass(frozen=True)
class TaskStats:
    """The statistics of one task name over a set of ended tasks."""

    task_name: str
    count: int
    """Tasks of this name that ended, refused ones (never started) included."""
    done_count: int
    """Of them, those that ended DONE."""
    started_count: int
    """Of them, those that started: the durations (running time) are theirs."""
    median_duration: timedelta | None
    """None when none started."""
    p95_duration: timedelta | None
    """The nearest-rank 95th percentile; None when none started."""

    @property
    def success_rate(self) -> float:
        """The share that ended DONE, from 0 to 1."""
        return self.done_count / self.count if self.count else 0.0


def percentile(sorted_values: list[timedelta], fraction: float) -> timedelta:
    """The nearest-rank percentile (`fraction` from 0 to 1) of a non-empty sorted list."""
    if not sorted_values:
        raise ValueError('percentile of no values')
    rank = max(math.ceil(fraction * len(sorted_values)), 1)
    return sorted_values[rank - 1]


def median(sorted_values: list[timedelta]) -> timedelta:
    """The median of a non-empty sorted list (the mean of the middle two for an even count)."""
    if not sorted_values:
        raise ValueError('median of no values')
    middle = len(sorted_values) // 2
    if len(sorted_values) % 2:
        return sorted_values[middle]
    return (sorted_values[middle - 1] + sorted_values[middle]) / 2


def _duration(task: EndedTask) -> timedelta | None:
    if task.started_at is None or task.ended_at is None:
        return None
    return max(task.ended_at - task.started_at - task.paused, timedelta(0))


def task_stats(tasks: Iterable[EndedTask]) -> list[TaskStats]:
    """The statistics of each task name among `tasks`, sorted by name."""
    # key: task name, value: its tasks
    by_name: dict[str, list[EndedTask]] = {}
    for task in tasks:
        by_name.setdefault(task.task_name, []).append(task)
    stats = []
    for name in sorted(by_name):
        named = by_name[name]
        durations = sorted(d for t in named if (d := _duration(t)) is not None)
        stats.append(
            TaskStats(
                task_name=name,
                count=len(named),
                done_count=sum(t.status is TaskStatus.DONE for t in named),
                started_count=len(durations),
                median_duration=median(durations) if durations else None,
                p95_duration=percentile(durations, 0.95) if durations else None,
            )
        )
    return stats
