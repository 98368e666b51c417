"""Pausing tasks: the `Pause` record of a TaskState, running time, and system/pause and resume.

A paused task stays active (status PAUSED); its running time does not count the time paused.
"""

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import TYPE_CHECKING, Any, TypeGuard

from task_manager.core.names import PAUSE as PAUSE_TASK
from task_manager.core.names import RESUME as RESUME_TASK
from task_manager.message_values import datetime_of_epoch

if TYPE_CHECKING:
    from task_manager.client import TaskResult


@dataclass(frozen=True)
class Pause:
    """One pause of a task: when and by whom it was paused, and resumed."""

    paused_at: datetime
    paused_by: str
    """The source of the system/pause task that paused it."""
    resumed_at: datetime | None = None
    """None while it is paused (or if it ended paused)."""
    resumed_by: str = ''
    """The source of the system/resume task; '' while it is paused."""

    def length(self, until: datetime) -> timedelta:
        """How long it was paused before `until` (an open pause lasts until then)."""
        end = until if self.resumed_at is None else min(self.resumed_at, until)
        return max(end - self.paused_at, timedelta(0))


def parse_pauses(text: str) -> list[Pause]:
    """The pauses of a TaskState's `pauses` JSON; items that are not pauses are left out."""
    try:
        items = json.loads(text or '[]')
    except json.JSONDecodeError:
        return []
    if not isinstance(items, list):
        return []
    return [pause for item in items if (pause := _pause(item)) is not None]


def _pause(item: Any) -> Pause | None:
    if not isinstance(item, dict):
        return None
    paused, resumed = item.get('paused'), item.get('resumed')
    if not _is_epoch(paused) or not (resumed is None or _is_epoch(resumed)):
        return None
    return Pause(
        paused_at=datetime_of_epoch(paused),
        paused_by=str(item.get('paused_by') or ''),
        resumed_at=None if resumed is None else datetime_of_epoch(resumed),
        resumed_by=str(item.get('resumed_by') or ''),
    )


def _is_epoch(value: Any) -> TypeGuard[float]:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def paused_time(pauses: Sequence[Pause], paused: timedelta, until: datetime) -> timedelta:
    """Time paused before `until`: from `pauses` when known (an open pause still counts),
    else `paused` (the task's paused_sec)."""
    if not pauses:
        return paused
    return sum((pause.length(until) for pause in pauses), timedelta(0))


def running_time(
    started_at: datetime, until: datetime, pauses: Sequence[Pause], paused: timedelta
) -> timedelta:
    """From `started_at` to `until`, less the time paused: the clock stops while paused."""
    return max(until - started_at - paused_time(pauses, paused, until), timedelta(0))


class RunsTasks:
    """What the client's method mixins use of TaskManagerClient (for the type checker)."""

    if TYPE_CHECKING:

        def run_task(
            self,
            task_name: str,
            task_data: dict[str, Any] | str | None = None,
            *,
            timeout_sec: float | None = None,
            **options: Any,
        ) -> TaskResult: ...


class PauseMethods(RunsTasks):
    """The pause and resume methods of TaskManagerClient."""

    def pause(
        self, task_ids: Sequence[str], *, source: str = 'python', timeout_sec: float | None = None
    ) -> 'TaskResult':
        """Pause active tasks by id through system/pause, and wait for its result.

        It ends DONE when every task is paused (one already paused counts), else ERROR; its
        result has `successful_pauses` and `errors` (one line per other id). `timeout_sec`:
        as for run_task (None: no limit).
        """
        data = {'task_ids': list(task_ids)}
        return self.run_task(PAUSE_TASK, data, source=source, timeout_sec=timeout_sec)

    def resume(
        self, task_ids: Sequence[str], *, source: str = 'python', timeout_sec: float | None = None
    ) -> 'TaskResult':
        """Resume paused tasks by id through system/resume, and wait for its result.

        It ends DONE when every task runs again, else ERROR; its result has
        `successful_resumes` and `errors` (one line per other id, e.g. one not paused).
        """
        data = {'task_ids': list(task_ids)}
        return self.run_task(RESUME_TASK, data, source=source, timeout_sec=timeout_sec)
