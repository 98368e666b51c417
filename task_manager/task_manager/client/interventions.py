"""An operator's interventions in running tasks: pausing them (system/pause and system/resume;
the `Pause` record is in records.py) and answering a waiting system/confirm through
/task_manager/confirm_task (ConfirmTask)."""

from collections.abc import Sequence
from dataclasses import dataclass

from task_manager_msgs.srv import ConfirmTask

from task_manager.client.records import TaskResult
from task_manager.client.services import ClientParts
from task_manager.core.names import CONFIRM_TASK_SERVICE
from task_manager.core.names import PAUSE as PAUSE_TASK
from task_manager.core.names import RESUME as RESUME_TASK


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


class Interventions(ClientParts):
    """TaskManagerClient's interventions: pauses and resumes by id (system/pause and
    system/resume), and answers to confirmations (/task_manager/confirm_task)."""

    def pause(
        self, task_ids: Sequence[str], *, source: str = 'python', timeout_sec: float | None = None
    ) -> TaskResult:
        """Pause active tasks by id through system/pause, and wait for its result.

        It ends DONE when every task is paused (one already paused counts), else ERROR; its
        result has `successful_pauses` and `errors` (one line per other id). `timeout_sec`:
        as for run_task (None: no limit).
        """
        data = {'task_ids': list(task_ids)}
        return self._system_task(PAUSE_TASK, data, source=source, timeout_sec=timeout_sec)

    def resume(
        self, task_ids: Sequence[str], *, source: str = 'python', timeout_sec: float | None = None
    ) -> TaskResult:
        """Resume paused tasks by id through system/resume, and wait for its result.

        It ends DONE when every task runs again, else ERROR; its result has
        `successful_resumes` and `errors` (one line per other id, e.g. one not paused).
        """
        data = {'task_ids': list(task_ids)}
        return self._system_task(RESUME_TASK, data, source=source, timeout_sec=timeout_sec)

    def confirm(
        self, task_id: str, *, reject: bool = False, comment: str = '', source: str = 'python'
    ) -> ConfirmAnswer:
        """Answer a waiting system/confirm: confirmed, it ends DONE; rejected, ERROR `rejected`;
        its result names `source` (`by`) and `comment`. Start one with start_task. An answer
        asked again is taken again."""
        request = ConfirmTask.Request(
            task_id=task_id, reject=reject, comment=comment, source=source
        )
        response = self._call(ConfirmTask, CONFIRM_TASK_SERVICE, request)
        return ConfirmAnswer(task_id, response.success, response.message, response.error_code)
