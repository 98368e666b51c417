"""Pausing and resuming active tasks (system/pause, system/resume, a mission's subtask).

How a task pauses is declared per task (`pause:` in its entry, see core/task_spec.py):
- `restart`: its server's goal is cancelled now (within cancel_timeout) and the same goal is
  sent again on resume. How a navigation goal is paused in practice.
- missions (system/mission) pause between subtasks: the running subtask goes on (or pauses
  with it, if it is `restart`), and the next one waits for the resume.
- `none` (the default): the task cannot be paused; asking says so.
A paused task stays active with status PAUSED; cancels, stops and conflicts end it CANCELED.
"""

from typing import Protocol, runtime_checkable

from rclpy.node import Node

from task_manager.core.errors import TaskRequestError
from task_manager.core.status import TaskStatus
from task_manager.core.task import TaskEnd
from task_manager.core.task_spec import PauseMode
from task_manager.rclpy_tools.futures import result_of
from task_manager.rclpy_tools.log import NodeLog
from task_manager.ros.parking_executor import spawn
from task_manager.ros.recording.task_changes import TaskChange, TaskChanges
from task_manager.ros.running.attempts import Attempts
from task_manager.ros.running.task_run import Runs, TaskRun


@runtime_checkable
class PausableExecution(Protocol):
    """An execution that pauses itself without stopping (a mission between its subtasks)."""

    def pause(self, source: str) -> None: ...

    def resume(self, source: str) -> None: ...


def _label(run: TaskRun) -> str:
    return f'task {run.task_id} ({run.record.task_name})'


class PauseControl:
    """Pauses and resumes active tasks; each call answers '' or why it could not."""

    def __init__(self, node: Node, runs: Runs, changes: TaskChanges, attempts: Attempts) -> None:
        self._node = node
        self._runs = runs
        self._changes = changes
        self._attempts = attempts
        self._log = NodeLog.of(node)

    async def pause(self, task_id: str, source: str) -> str:
        """Pause an active task for `source`; '' once it is paused (or already was)."""
        run = self._runs.get(task_id)
        if run is None:
            return f'no active task {task_id!r} to pause'
        status, mode = run.record.status, run.record.spec.pause
        if status is TaskStatus.PAUSED:
            return ''
        if mode is PauseMode.NONE:
            return (
                f'{_label(run)} cannot be paused: its entry declares pause: none (the default); '
                'pause: restart pauses an action task by cancelling its goal and sending it '
                'again on resume'
            )
        cancelling = run.record.cancel_reason is not None
        if status is not TaskStatus.IN_PROGRESS or run.pausing or cancelling:
            state = 'being cancelled' if cancelling else str(status)
            return f'{_label(run)} is {state}; only a running task can be paused'
        if isinstance(run.execution, PausableExecution):
            run.execution.pause(source)
            self._changed(run, TaskStatus.PAUSED, source)
            return ''
        return await self._pause_by_restart(run, source)

    async def _pause_by_restart(self, run: TaskRun, source: str) -> str:
        execution = run.execution
        assert execution is not None, 'a task in progress has its execution'
        timeout_sec = run.record.spec.cancel_timeout_sec
        run.pausing = True
        try:
            await execution.cancel(timeout_sec)
        finally:
            run.pausing = False
        if run.finished.done():
            return f'{_label(run)} ended before it could be paused'
        if not execution.outcome.done():
            return (
                f'{_label(run)}: its goal was not cancelled within its cancel_timeout of '
                f'{timeout_sec} s; the task goes on, not paused'
            )
        end: TaskEnd = result_of(execution.outcome)
        if run.record.cancel_reason is not None or end.status is not TaskStatus.CANCELED:
            self._attempts.end(
                run, TaskEnd(TaskStatus.CANCELED) if run.record.cancel_reason else end
            )
            return f'{_label(run)} ended before it could be paused'
        run.execution = None
        self._changed(run, TaskStatus.PAUSED, source)
        return ''

    async def resume(self, task_id: str, source: str) -> str:
        """Resume a paused task for `source`; '' once it runs again."""
        run = self._runs.get(task_id)
        if run is None:
            return f'no active task {task_id!r} to resume'
        if run.record.status is not TaskStatus.PAUSED:
            return (
                f'{_label(run)} is not paused (it is {run.record.status}); '
                'only a paused task can be resumed'
            )
        if isinstance(run.execution, PausableExecution):
            run.execution.resume(source)
            self._changed(run, TaskStatus.IN_PROGRESS, source)
            return ''
        if run.starting:
            return f'{_label(run)} is already resuming'
        try:
            execution = await self._attempts.start_on_server(run)
        except TaskRequestError as error:
            end = TaskEnd(TaskStatus.ERROR, {'error': str(error)}, error.error_code)
            self._attempts.end(run, end)
            return f'{_label(run)} could not be resumed and ended ERROR: {error}'
        if run.finished.done():  # ended (by force, at shutdown) while its goal was sent again
            spawn(self._node, execution.cancel(run.record.spec.cancel_timeout_sec))
            return f'{_label(run)} ended while it resumed'

        def resumed() -> None:
            self._changed(run, TaskStatus.IN_PROGRESS, source)
            self._attempts.attach(run, execution)

        self._attempts.track(run, execution, resumed)
        return ''

    def _changed(self, run: TaskRun, status: TaskStatus, source: str) -> None:
        record = run.record
        if status is TaskStatus.PAUSED:
            record.mark_paused(source)
            self._changes.changed(record, TaskChange.PAUSED)
        else:
            record.mark_resumed(source)
            self._changes.changed(record, TaskChange.RESUMED)
        verb = 'paused' if status is TaskStatus.PAUSED else 'resumed'
        self._log.info(f'{_label(run)} {verb} by {source!r}')
