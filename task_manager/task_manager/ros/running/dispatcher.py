"""Runs task requests: admission, the task's turn, its attempts, and its end.

Everything here runs on the node's executor thread; each request is one coroutine that
awaits futures, so a waiting task costs no thread and an unrelated request never waits
behind another one's server or cancel. The path of a request, top to bottom:
`run` admits it (`_admit`), waits for its turn (AdmissionControl.turn: the queue, the tasks it
pre-empts), attempts it on its server (Attempts.run) and ends it (`_finish`: stored, then
announced through TaskChanges).
"""

import uuid
from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from rclpy.task import Future

from task_manager.core.admission.arbiter import Verdict
from task_manager.core.bounds import task_data_problem
from task_manager.core.errors import TaskRequestError
from task_manager.core.status import CancelReason, ErrorCode, TaskStatus
from task_manager.core.task import TaskEnd, TaskRecord, TaskRequest
from task_manager.core.task_spec import InterfaceName, TaskKind, TaskSpec
from task_manager.core.text.request_text import loggable, request_problem
from task_manager.messages.json_codec import TaskDataError
from task_manager.rclpy_tools.futures import completed_future, resolved, result_of, wait_for
from task_manager.rclpy_tools.log import NodeLog
from task_manager.ros.recording.task_changes import TaskChange, TaskChanges
from task_manager.ros.running.admission_control import AdmissionControl
from task_manager.ros.running.attempts import Attempts
from task_manager.ros.running.execution import TaskCatalog
from task_manager.ros.running.task_run import Runs, TaskRun

# How long tasks ended by force at shutdown may take to report their results.
FORCED_END_TIMEOUT_SEC = 1.0


def _unknown_spec(task_name: str) -> TaskSpec:
    return TaskSpec(task_name, '', InterfaceName('', TaskKind.SYSTEM, ''))


class TaskDispatcher:
    """Every request's path, from its admission to its end; the table of runs it fills."""

    def __init__(
        self,
        node: Node,
        catalog: TaskCatalog,
        runs: Runs,
        changes: TaskChanges,
        admission: AdmissionControl,
        attempts: Attempts,
    ) -> None:
        self._node = node
        self._catalog = catalog
        self._runs = runs
        self._changes = changes
        self._admission = admission
        self._attempts = attempts
        self._log = NodeLog.of(node)
        self._closing_reason = ''
        # completes once no task is active; replaced whenever a task is admitted
        self._idle: Future[None] = completed_future()

    # ---- running a request -------------------------------------------------------------

    async def run(
        self, request: TaskRequest, on_admitted: Callable[[TaskRecord], None] | None = None
    ) -> TaskRecord:
        """Run `request` to its end and return its final record. Never raises.

        `on_admitted` is called with the record once the request is tracked, before it starts.
        """
        record, run = self._admit(request)
        if run is None:
            await resolved(self._node, self._changes.ended(record, was_listed=False))
            return record
        if on_admitted is not None:
            on_admitted(record)
        try:
            await self._admission.turn(run)
            end = await self._attempts.run(run)
        except TaskRequestError as error:
            self._log.warning(f'task {record.task_id} ({record.task_name}) failed: {error}')
            end = TaskEnd(TaskStatus.ERROR, {'error': str(error)}, error.error_code)
        except Exception as error:  # the callback boundary: log, fail the task, keep serving
            self._log.error(f'task {record.task_id} ({record.task_name}) crashed: {error!r}')
            end = TaskEnd(
                TaskStatus.ERROR,
                {'error': f'the Task Manager failed to run the task: {error!r}'},
                ErrorCode.TASK_START_FAILED,
            )
        # Ended here too, so that whoever waits on this task (a cancel) sees it end.
        self._attempts.end(run, end)
        await resolved(self._node, self._finish(run))
        return record

    def refuse(self, request: TaskRequest, code: ErrorCode, reason: str) -> TaskRecord:
        """End a request that must not run (e.g. an invalid subtask): logged and published."""
        record = self._reject(self._new_record(request), code, reason)
        self._changes.ended(record, was_listed=False)
        return record

    def cancel(self, task_id: str, reason: CancelReason) -> Future[bool]:
        """Cancel an active task; the future completes with True once it has ended in time.

        An id that is not active completes True at once (there is nothing left to cancel).
        False means the task did not end within its cancel_timeout and is still running (see
        Attempts.cancel).
        """
        run = self._runs.get(task_id)
        return completed_future(True) if run is None else self._attempts.cancel(run, reason)

    def record(self, task_id: str) -> TaskRecord | None:
        """The record of an active task; None when no active task has this id."""
        run = self._runs.get(task_id)
        return run.record if run is not None else None

    def records(self) -> list[TaskRecord]:
        """The active tasks' records, in the order they came."""
        return [run.record for run in self._runs]

    def cancelled_by_stop(self) -> list[TaskRecord]:
        """The active tasks that system/stop cancels (declared cancel_on_stop)."""
        return [run.record for run in self._runs.cancelled_by_stop()]

    def _new_record(self, request: TaskRequest) -> TaskRecord:
        runner = self._catalog.get(request.task_name)
        spec = runner.spec if runner else _unknown_spec(request.task_name)
        task_id = request.task_id or str(uuid.uuid4())
        record = TaskRecord(
            task_id, spec, request.source, parent_id=request.parent_id, task_data=request.task_data
        )
        self._changes.changed(record, TaskChange.RECEIVED)
        return record

    def _admit(self, request: TaskRequest) -> tuple[TaskRecord, TaskRun | None]:
        """Track the request, or end it at once (its run is None then)."""
        record = self._new_record(request)
        task_id = record.task_id
        if problem := request_problem(task_id, request.task_name, request.source):
            return self._reject(record, ErrorCode.INVALID_REQUEST, problem), None
        if problem := task_data_problem(request.task_data):
            return self._reject(record, ErrorCode.INVALID_REQUEST, problem), None
        runner = self._catalog.get(request.task_name)
        if runner is None:
            reason = self._catalog.unknown_task_reason(request.task_name)
            return self._reject(record, ErrorCode.UNKNOWN_TASK, reason), None
        if self._runs.get(task_id) is not None:
            reason = (
                f'task id {task_id!r} is in use by an active task; '
                'an id may be used again once its task has ended'
            )
            return self._reject(record, ErrorCode.DUPLICATE_TASK_ID, reason), None
        if self._closing_reason:
            return self._reject(record, ErrorCode.TASK_START_FAILED, self._closing_reason), None
        if problem := request.options.problem():
            return self._reject(record, ErrorCode.INVALID_REQUEST, problem), None
        try:
            message = runner.parse(request.task_data, task_id)
        except TaskDataError as error:
            code = ErrorCode.TASK_DATA_PARSING_FAILED
            return self._reject(record, code, str(error), error.result), None
        record.priority = self._admission.priority_of(request, record)
        claimed = runner.claimed_resources(message)
        decision = self._admission.decide(record, request.options, claimed)
        if decision.verdict is Verdict.REFUSE:
            return self._reject(record, decision.error_code, decision.reason), None
        run = TaskRun(record, message, options=request.options)
        self._runs.admit(run)
        if self._idle.done():
            self._idle = Future()
        run.preemptions = decision.preemptions
        if decision.verdict is Verdict.QUEUE:
            self._admission.queue(run, decision)
        return record, run

    def _reject(
        self,
        record: TaskRecord,
        code: ErrorCode,
        reason: str,
        result: dict[str, Any] | None = None,
    ) -> TaskRecord:
        """End a request that will not run: ERROR, its result `{"error": reason}` (and `result`)."""
        self._log.warning(
            f'task {loggable(record.task_id)} ({loggable(record.task_name)}) from '
            f'{loggable(record.source)!r} rejected, {code}: {reason}',
        )
        record.mark_ended(TaskStatus.ERROR, {**(result or {}), 'error': reason}, code)
        return record

    # ---- closing ---------------------------------------------------------------------------

    async def close(self, reason: str, timeout_sec: float) -> bool:
        """Refuse new tasks, cancel every active one, and wait (bounded) until all have ended.

        Tasks that do not end in time (e.g. services still running) end ERROR, so every
        request still gets its result. True when every task ended by itself in time.
        """
        self._closing_reason = reason
        self._attempts.close()
        for run in self._runs:
            self._attempts.cancel(run, CancelReason.SHUTDOWN)
        if await wait_for(self._node, self._idle, timeout_sec):
            return True
        for run in self._runs:
            record = run.record
            self._log.warning(f'task {record.task_id} ({record.task_name}) did not end: {reason}')
            self._attempts.end(run, TaskEnd(TaskStatus.ERROR, {'error': reason}))
        await wait_for(self._node, self._idle, FORCED_END_TIMEOUT_SEC)
        return False

    # ---- ending ----------------------------------------------------------------------------

    def _finish(self, run: TaskRun) -> Future[None]:
        """End the task; the future completes once its end is stored and announced."""
        record, end = run.record, result_of(run.finished)
        was_listed = record.status.is_listed
        # the server's result as it sent it: why the task ended is in its decisions and events
        record.mark_ended(end.status, end.result, end.error_code)
        self._admission.released(run)
        self._runs.remove(record.task_id)
        announced = self._changes.ended(record, was_listed)
        if not len(self._runs) and not self._idle.done():
            self._idle.set_result(None)
        ran_sec = (
            f' after {record.ended_at - record.started_at:.2f} s'
            if record.started_at is not None and record.ended_at is not None
            else ''
        )
        self._log.info(
            f'task {record.task_id} ({record.task_name}) from {record.source!r} ended '
            f'{record.status}{ran_sec}' + (f' ({record.error_code})' if record.error_code else ''),
        )
        return announced
