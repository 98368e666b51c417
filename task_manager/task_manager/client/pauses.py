"""Pausing tasks: system/pause and system/resume (the `Pause` record is in records.py)."""

from collections.abc import Sequence

from task_manager.client.records import TaskResult
from task_manager.client.services import RunTask
from task_manager.core.names import PAUSE as PAUSE_TASK
from task_manager.core.names import RESUME as RESUME_TASK


class Pauses:
    """Pauses and resumes tasks by id, through `run_task`."""

    def __init__(self, run_task: RunTask) -> None:
        self._run_task = run_task

    def pause(
        self, task_ids: Sequence[str], *, source: str = 'python', timeout_sec: float | None = None
    ) -> TaskResult:
        """See TaskManagerClient.pause."""
        data = {'task_ids': list(task_ids)}
        return self._run_task(PAUSE_TASK, data, source=source, timeout_sec=timeout_sec)

    def resume(
        self, task_ids: Sequence[str], *, source: str = 'python', timeout_sec: float | None = None
    ) -> TaskResult:
        """See TaskManagerClient.resume."""
        data = {'task_ids': list(task_ids)}
        return self._run_task(RESUME_TASK, data, source=source, timeout_sec=timeout_sec)
