"""Runs task requests: admission, conflict resolution, start, tracking, cancel and end.

Everything here runs on the node's executor thread; each request is one coroutine that
awaits futures, so a waiting task costs no thread and an unrelated request never waits
behind another one's server or cancel.
"""

import uuid
from collections.abc import Callable, Coroutine
from typing import Any, Protocol

from rclpy.node import Node
from rclpy.task import Future

from task_manager.core.admission.arbiter import DEFAULT_MAX_QUEUED, Verdict
from task_manager.core.admission.decisions import DecisionKind
from task_manager.core.bounds import task_data_problem
from task_manager.core.errors import TaskRequestError
from task_manager.core.history.store import TaskHistory
from task_manager.core.registry import TaskRegistry
from task_manager.core.request_text import loggable, request_problem
from task_manager.core.status import CancelReason, ErrorCode, TaskStatus
from task_manager.core.task import TaskEnd, TaskRecord, TaskRequest
from task_manager.core.task_spec import InterfaceName, TaskKind, TaskSpec
from task_manager.messages.json_codec import TaskDataError
from task_manager.rclpy_tools.futures import (
    all_completed,
    completed_future,
    first_completed,
    resolved,
    result_of,
    wait_for,
)
from task_manager.ros.recording import task_log
from task_manager.ros.recording.active_tasks import ActiveTasksPublication
from task_manager.ros.recording.history_writer import HistoryWriter
from task_manager.ros.recording.task_events import TaskEventStream
from task_manager.ros.running.admission_control import AdmissionControl
from task_manager.ros.running.execution import Execution, TaskRunner
from task_manager.ros.running.pause_control import PauseControl
from task_manager.ros.running.task_run import TaskRun

# How long tasks ended by force at shutdown may take to report their results.
FORCED_END_TIMEOUT_SEC = 1.0


class TaskReporter(Protocol):
    """Where the dispatcher tells the world about tasks (the node's publishers)."""

    def publish_active(self, records: list[TaskRecord]) -> None: ...

    def publish_result(self, record: TaskRecord) -> None: ...


def _unknown_spec(task_name: str) -> TaskSpec:
    return TaskSpec(task_name, '', InterfaceName('', TaskKind.SYSTEM, ''))


class TaskDispatcher:
    """Owns the registry of active tasks and every request's path through it."""

    def __init__(
        self,
        node: Node,
        runners: dict[str, TaskRunner],
        reporter: TaskReporter,
        spawn: Callable[[Coroutine[Any, Any, Any]], Any],
        events: TaskEventStream,
        history: TaskHistory,
        max_queued: int = DEFAULT_MAX_QUEUED,
        source_priorities: dict[str, int] | None = None,
    ) -> None:
        self.registry = TaskRegistry()
        self.events = events
        self.history = HistoryWriter(node, history, self.announce_end)
        self.runners_by_name = runners
        self.node = node
        self._reporter = reporter
        self.spawn = spawn
        self.log = node.get_logger()
        # key: task id, value: the run state of the admitted task, until it ends
        self.runs_by_id: dict[str, TaskRun] = {}
        self._closing_reason = ''
        self._active = ActiveTasksPublication(node, self.registry, reporter)
        # completes once no task is active; replaced whenever a task is admitted
        self._idle: Future = completed_future()
        self.pauses = PauseControl(self)
        self.admission = AdmissionControl(self, max_queued, source_priorities or {})

    @property
    def closing(self) -> bool:
        """Shutting down: no new task, no new attempt."""
        return bool(self._closing_reason)

    # ---- running a request -------------------------------------------------------------

    async def run(
        self, request: TaskRequest, on_admitted: Callable[[TaskRecord], None] | None = None
    ) -> TaskRecord:
        """Run `request` to its end and return its final record. Never raises.

        `on_admitted` is called with the record once the request is tracked, before it starts.
        """
        record, run = self._admit(request)
        if run is None:
            await resolved(self.node, self._publish_end(record))
            return record
        if on_admitted is not None:
            on_admitted(record)
        try:
            end = await self._start_and_wait(run)
        except TaskRequestError as error:
            self.log.warning(f'task {record.task_id} ({record.task_name}) failed: {error}')
            end = TaskEnd(TaskStatus.ERROR, {'error': str(error)}, error.error_code)
        except Exception as error:  # the callback boundary: log, fail the task, keep serving
            self.log.error(f'task {record.task_id} ({record.task_name}) crashed: {error!r}')
            end = TaskEnd(
                TaskStatus.ERROR,
                {'error': f'the Task Manager failed to run the task: {error!r}'},
                ErrorCode.TASK_START_FAILED,
            )
        # Settled here too, so that whoever waits on this task (a cancel) sees it end.
        run.settle(end)
        await resolved(self.node, self._finish(run))
        return record

    def refuse(self, request: TaskRequest, code: ErrorCode, reason: str) -> TaskRecord:
        """End a request that must not run (e.g. an invalid subtask): logged and published."""
        record = self._reject(self._new_record(request), code, reason)
        self._publish_end(record)
        return record

    def unknown_task_reason(self, task_name: str) -> str:
        """Why a task name is refused, with the names that would be accepted."""
        known = ', '.join(sorted(self.runners_by_name))
        return f'unknown task {task_name!r}; declared tasks: {known}'

    def _new_record(self, request: TaskRequest) -> TaskRecord:
        runner = self.runners_by_name.get(request.task_name)
        spec = runner.spec if runner else _unknown_spec(request.task_name)
        task_id = request.task_id or str(uuid.uuid4())
        record = TaskRecord(
            task_id, spec, request.source, parent_id=request.parent_id, task_data=request.task_data
        )
        self.events.received(record)
        self.history.changed(record)
        return record

    def _admit(self, request: TaskRequest) -> tuple[TaskRecord, TaskRun | None]:
        """Track the request, or end it at once (its run is None then)."""
        record = self._new_record(request)
        task_id = record.task_id
        if problem := request_problem(task_id, request.task_name, request.source):
            return self._reject(record, ErrorCode.INVALID_REQUEST, problem), None
        if problem := task_data_problem(request.task_data):
            return self._reject(record, ErrorCode.INVALID_REQUEST, problem), None
        runner = self.runners_by_name.get(request.task_name)
        if runner is None:
            reason = self.unknown_task_reason(request.task_name)
            return self._reject(record, ErrorCode.UNKNOWN_TASK, reason), None
        if self.registry.get(task_id) is not None:
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
        record.priority = self.admission.priority_of(request, record)
        claimed = getattr(runner, 'claimed_resources', None)
        extra = claimed(message) if claimed is not None else frozenset()
        decision = self.admission.decide(record, request.options, extra)
        if decision.verdict is Verdict.REFUSE:
            return self._reject(record, decision.error_code, decision.reason), None
        self.registry.admit(record)
        if self._idle.done():
            self._idle = Future()
        run = self.runs_by_id[task_id] = TaskRun(record, message, options=request.options)
        run.preemptions = decision.preemptions
        if decision.verdict is Verdict.QUEUE:
            self.admission.queue(run, decision)
        return record, run

    def _reject(
        self,
        record: TaskRecord,
        code: ErrorCode,
        reason: str,
        result: dict[str, Any] | None = None,
    ) -> TaskRecord:
        """End a request that will not run: ERROR, its result `{"error": reason}` (and `result`)."""
        task_log.warning(
            self.log,
            f'task {loggable(record.task_id)} ({loggable(record.task_name)}) from '
            f'{loggable(record.source)!r} rejected, {code}: {reason}',
        )
        record.mark_ended(TaskStatus.ERROR, {**(result or {}), 'error': reason}, code)
        return record

    async def _start_and_wait(self, run: TaskRun) -> TaskEnd:
        record = run.record
        if run.dequeued is not None and not run.finished.done():
            await resolved(self.node, first_completed([run.dequeued, run.finished]))
        if not run.finished.done():  # not cancelled as it was admitted (or while queued)
            await self._resolve_conflicts(run)
        if run.finished.done():  # cancelled before it started: it pre-empts nothing
            return result_of(run.finished)
        try:
            execution = await self.start_on_server(run)
        except TaskRequestError as error:
            if record.cancel_reason is not None:
                # Cancelled before its server accepted it: it did not run, as its canceller
                # asked; why it could not have started is kept in its result.
                return TaskEnd(TaskStatus.CANCELED, {'error': str(error)})
            end = TaskEnd(TaskStatus.ERROR, {'error': str(error)}, error.error_code)
            if self.admission.attempt_end(run, end) is not None:
                raise
            await resolved(self.node, run.finished)  # a retry follows
            return result_of(run.finished)
        self.track(run, execution, lambda: self.began(run, execution))
        await resolved(self.node, run.finished)
        return result_of(run.finished)

    def track(self, run: TaskRun, execution: Execution, steps: Callable[[], None]) -> None:
        """Carry out `steps`, which track a task now running on its server (mark it started,
        attach its execution, arm its timeouts). Should one fail, the goal must not run on
        untracked: it is cancelled, and the task ends ERROR once its server says it has ended,
        or once its cancel_timeout has passed (then its result says the goal may still run)."""
        try:
            steps()
        except Exception as error:  # the callback boundary: a bug of ours must not free a robot
            self.log.error(
                f'task {run.task_id} ({run.record.task_name}) could not be tracked once started: '
                f'{error!r}; cancelling it on its server'
            )
            run.execution = None  # its end is the withdrawal's, not the server's result
            self.spawn(self._withdraw(run, execution, error))

    async def _withdraw(self, run: TaskRun, execution: Execution, error: Exception) -> None:
        timeout_sec = run.record.spec.cancel_timeout_sec
        if await execution.cancel(timeout_sec):
            what = 'it was cancelled on its server'
        else:
            what = (
                f'its cancel was not confirmed within cancel_timeout {timeout_sec:g} s: '
                'the goal may still run'
            )
        reason = f'the Task Manager failed to track the task once started ({error!r}); {what}'
        run.settle(TaskEnd(TaskStatus.ERROR, {'error': reason}, ErrorCode.TASK_START_FAILED))

    def began(self, run: TaskRun, execution: Execution) -> None:
        """An attempt runs on its server: the task is IN_PROGRESS (once) and its timeouts armed."""
        record = run.record
        if not record.status.is_started:
            record.mark_started()
            decided = record.decisions[-1].reason if record.decisions else ''
            self.events.started(record, decided if run.dequeued or run.preemptions else '')
            self.history.changed(record)
            self.log.debug(
                f'task {record.task_id} ({record.task_name}) from {record.source!r} started'
            )
        self.attach(run, execution)
        self.admission.attempt_started(run)

    async def start_on_server(self, run: TaskRun) -> Execution:
        """Start the task on its server (again, on resume); raises TaskRequestError."""
        run.starting = True
        run.started = Future()
        try:
            return await self.runners_by_name[run.record.task_name].start(run.message, run.record)
        finally:
            run.starting = False
            run.started.set_result(None)

    def attach(self, run: TaskRun, execution: Execution) -> None:
        """Track the task's execution on its server; its end is the task's end."""
        run.execution = execution
        self.publish_active_soon()
        execution.outcome.add_done_callback(lambda done: self._on_outcome(run, execution, done))
        if run.record.cancel_reason is not None:  # a cancel arrived while the task was starting
            self._cancel_future(run, run.record.cancel_reason)

    def _on_outcome(self, run: TaskRun, execution: Execution, done: Future[TaskEnd]) -> None:
        end = result_of(done)
        if run.execution is not execution:  # a goal ended by a pause, replaced on resume
            return
        if run.pausing and end.status is TaskStatus.CANCELED and run.record.cancel_reason is None:
            return  # the pause's own cancel: the task goes on, paused
        final = self.admission.attempt_end(run, end)
        if final is not None:  # else another attempt follows (retry)
            run.settle(final)

    async def _resolve_conflicts(self, run: TaskRun) -> None:
        record = run.record
        run.preempted = True
        conflicts = []
        for preemption in run.preemptions:
            victim = self.runs_by_id.get(preemption.victim.task_id)
            if victim is not None and not victim.finished.done():
                victim.record.note(DecisionKind.PREEMPTED, preemption.reason)
                conflicts.append(victim.record)
        claim = self.admission.arbiter.holders.get(record.task_id)
        for ending in self.admission.arbiter.still_ending(claim) if claim is not None else []:
            other = self.runs_by_id.get(ending.task_id)
            if other is not None and other.record not in conflicts:
                conflicts.append(other.record)
        if not conflicts:
            return
        self.log.info(
            f'task {record.task_id} ({record.task_name}) cancels conflicting task(s) '
            + ', '.join(f'{c.task_id} ({c.task_name})' for c in conflicts)
        )
        cancels = [self.cancel(c.task_id, CancelReason.CONFLICT) for c in conflicts]
        await resolved(self.node, first_completed([all_completed(cancels), run.finished]))
        if run.finished.done():
            return
        stuck = [c for c, cancel in zip(conflicts, cancels, strict=True) if not cancel.result()]
        if stuck:
            raise TaskRequestError(
                ErrorCode.TASK_START_FAILED,
                'could not cancel conflicting task(s) within their cancel_timeout: '
                + ', '.join(f'{c.task_id} ({c.task_name})' for c in stuck),
            )

    # ---- cancelling ----------------------------------------------------------------------

    def cancel(self, task_id: str, reason: CancelReason) -> Future:
        """Cancel an active task; the future completes with True once it has ended in time.

        An id that is not active completes True at once (there is nothing left to cancel).
        False means the task did not end within its cancel_timeout and is still running
        (e.g. a service call, which cannot be interrupted): it ends when its server says so.
        """
        run = self.runs_by_id.get(task_id)
        if run is None:
            return completed_future(True)
        return self._cancel_future(run, reason)

    def _cancel_future(self, run: TaskRun, reason: CancelReason) -> Future[bool]:
        if run.cancel_in_flight is not None:
            return run.cancel_in_flight
        record = run.record
        record.request_cancel(reason)
        if run.finished.done():
            return completed_future(True)
        if run.execution is None and not run.starting:  # not started yet, or paused by restart
            run.settle(TaskEnd(TaskStatus.CANCELED))
            return completed_future(True)
        cancelled: Future[bool] = Future()
        run.cancel_in_flight = cancelled
        self.spawn(self._cancel_started(run, reason, cancelled))
        return cancelled

    async def _cancel_started(
        self, run: TaskRun, reason: CancelReason, cancelled: Future[bool]
    ) -> None:
        """Cancel a task that is starting or running, within its cancel_timeout."""
        record = run.record
        timeout_sec = record.spec.cancel_timeout_sec
        clock = self.node.get_clock()
        began = clock.now()
        await wait_for(self.node, first_completed([run.started, run.finished]), timeout_sec)
        execution = run.execution
        ok = run.finished.done()
        if not ok and execution is not None:
            remaining_sec = timeout_sec - (clock.now() - began).nanoseconds / 1e9
            ok = await execution.cancel(remaining_sec) or run.finished.done()
        if not ok:
            self.log.warning(
                f'task {record.task_id} ({record.task_name}): cancel ({reason}) did not '
                f'complete within cancel_timeout {timeout_sec} s; the task goes on'
            )
        run.cancel_in_flight = None
        cancelled.set_result(ok)

    async def close(self, reason: str, timeout_sec: float) -> bool:
        """Refuse new tasks, cancel every active one, and wait (bounded) until all have ended.

        Tasks that do not end in time (e.g. services still running) end ERROR, so every
        request still gets its result. True when every task ended by itself in time.
        """
        self._closing_reason = reason
        for record in self.registry:
            self.cancel(record.task_id, CancelReason.SHUTDOWN)
        if await wait_for(self.node, self._idle, timeout_sec):
            return True
        for run in list(self.runs_by_id.values()):
            record = run.record
            self.log.warning(f'task {record.task_id} ({record.task_name}) did not end: {reason}')
            run.settle(TaskEnd(TaskStatus.ERROR, {'error': reason}))
        await wait_for(self.node, self._idle, FORCED_END_TIMEOUT_SEC)
        return False

    # ---- ending ----------------------------------------------------------------------------

    def _finish(self, run: TaskRun) -> Future[None]:
        """End the task; the future completes once its end is stored and announced."""
        record, end = run.record, result_of(run.finished)
        was_active = record.status.is_listed
        # the server's result as it sent it: why the task ended is in its decisions and events
        record.mark_ended(end.status, end.result, end.error_code)
        self.registry.remove(record.task_id)
        self.admission.released(run)
        del self.runs_by_id[record.task_id]
        if was_active:
            self._active.ended(record)
        announced = self._publish_end(record)
        if not len(self.registry) and not self._idle.done():
            self._idle.set_result(None)
        ran_sec = (
            f' after {record.ended_at - record.started_at:.2f} s'
            if record.started_at is not None and record.ended_at is not None
            else ''
        )
        task_log.info(
            self.log,
            f'task {record.task_id} ({record.task_name}) from {record.source!r} ended '
            f'{record.status}{ran_sec}' + (f' ({record.error_code})' if record.error_code else ''),
        )
        return announced

    def _publish_end(self, record: TaskRecord) -> Future[None]:
        """Store the task's end; it is announced once committed (see history_writer.py)."""
        return self.history.ended(record)

    def announce_end(self, record: TaskRecord) -> None:
        """ENDED on the event stream and the result on /task_manager/results."""
        self.events.ended(record)
        self._reporter.publish_result(record)

    def publish_active_soon(self) -> None:
        """Publish active_tasks soon (see active_tasks.py for when)."""
        self._active.changed()
