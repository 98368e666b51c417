"""An operator's interventions in running tasks: pausing them (system/pause and system/resume;
the `Pause` record is in records.py) and answering a waiting system/confirm through
/task_manager/confirm_task (ConfirmTask)."""

from collections.abc import Sequence
from dataclasses import dataclass

from task_manager_msgs.srv import ConfirmTask

from task_manager.client.records import TaskResult
from task_manager.client.services import CallService, RunTask
from task_manager.core.names import CONFIRM_TASK_SERVICE
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


@dataclass(frozen=True)
class ConfirmAnswer:
    """What the Task Manager said to an answer: taken (the task ends with it), or why not."""

    task_id: str
    taken: bool
    """True when the confirmation ends with this answer (DONE confirmed, ERROR rejected)."""
    message: str = ''
    """Why it was not taken: which task it is and why it takes no answer."""
    error_code: str = ''
    """Empty when taken; else `not_found` (no such task, active or kept), `not_waiting` (not a
    system/confirm waiting for its answer) or `invalid_request` (a refused comment or source)."""


class Confirmations:
    """Answers confirmations through `call` (an answer asked again is taken again)."""

    def __init__(self, call: CallService) -> None:
        self._call = call

    def confirm(self, task_id: str, reject: bool, comment: str, source: str) -> ConfirmAnswer:
        """See TaskManagerClient.confirm."""
        request = ConfirmTask.Request(
            task_id=task_id, reject=reject, comment=comment, source=source
        )
        response = self._call(ConfirmTask, CONFIRM_TASK_SERVICE, request)
        return ConfirmAnswer(task_id, response.success, response.message, response.error_code)
