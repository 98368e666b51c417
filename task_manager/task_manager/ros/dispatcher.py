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

from task_manager.core.errors import TaskRequestError
from task_manager.core.history import TaskHistory
from task_manager.core.registry import TaskRegistry
from task_manager.core.status import CancelReason, ErrorCode, TaskStatus
from task_manager.core.task import TaskEnd, TaskRecord, TaskRequest
from task_manager.core.task_spec import InterfaceName, TaskKind, TaskSpec
from task_manager.ros.execution import Execution, TaskRunner
from task_manager.ros.futures import (
    all_completed,
    completed_future,
    first_completed,
    resolved,
    result_of,
    wait_for,
)
from task_manager.ros.history_writer import HistoryWriter
from task_manager.ros.message_json import TaskDataError
from task_manager.ros.task_events import TaskEventStream

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
    ) -> None:
        self.registry = TaskRegistry()
        self.events = events
        self.history = HistoryWriter(node, history, spawn, self.announce_end)
        self.runners_by_name = runners
        self.node = node
        self._reporter = reporter
        self._spawn = spawn
        self._log = node.get_logger()
        # key: task id, value: completes with the task's TaskEnd (first writer wins)
        self._finished: dict[str, Future[TaskEnd]] = {}
        # key: task id, value: completes once the task has started on its server, or failed to
        self._started: dict[str, Future] = {}
        # key: task id, value: the running task on its server
        self._executions: dict[str, Execution] = {}
        # key: task id, value: completes with True when the cancel in flight ended the task
        self._cancels_in_flight: dict[str, Future] = {}
        # ids of tasks whose start on their server is in flight
        self._starting_ids: set[str] = set()
        self._closing_reason = ''
        # Tasks that ended since the last active_tasks publication: shown once more, with
        # their end status, before they leave the list.
        self._ended_unpublished: list[TaskRecord] = []
        self._publication_pending = False
        # completes once no task is active; replaced whenever a task is admitted
        self._idle: Future = completed_future()

    # ---- running a request -------------------------------------------------------------

    async def run(
        self, request: TaskRequest, on_admitted: Callable[[TaskRecord], None] | None = None
    ) -> TaskRecord:
        """Run `request` to its end and return its final record. Never raises.

        `on_admitted` is called with the record once the request is tracked, before it starts.
        """
        record, message = self._admit(request)
        if record.is_final:
            await resolved(self.node, self._publish_end(record))
            return record
        if on_admitted is not None:
            on_admitted(record)
        try:
            end = await self._start_and_wait(record, message)
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
        # Settled here too, so that whoever waits on this task (a cancel) sees it end.
        self._settle(record.task_id, end)
        await resolved(self.node, self._finish(record, result_of(self._finished[record.task_id])))
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

    def _admit(self, request: TaskRequest) -> tuple[TaskRecord, Any]:
        record = self._new_record(request)
        task_id = record.task_id
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
        try:
            message = runner.parse(request.task_data, task_id)
        except TaskDataError as error:
            code = ErrorCode.TASK_DATA_PARSING_FAILED
            return self._reject(record, code, str(error), error.result), None
        self.registry.admit(record)
        if self._idle.done():
            self._idle = Future()
        self._finished[task_id] = Future()
        self._started[task_id] = Future()
        return record, message

    def _reject(
        self,
        record: TaskRecord,
        code: ErrorCode,
        reason: str,
        result: dict[str, Any] | None = None,
    ) -> TaskRecord:
        """End a request that will not run: ERROR, its result `{"error": reason}` (and `result`)."""
        self._log.warning(
            f'task {record.task_id} ({record.task_name}) from {record.source!r} '
            f'rejected, {code}: {reason}'
        )
        record.mark_ended(TaskStatus.ERROR, {**(result or {}), 'error': reason}, code)
        return record

    async def _start_and_wait(self, record: TaskRecord, message: Any) -> TaskEnd:
        task_id = record.task_id
        finished = self._finished[task_id]
        await self._resolve_conflicts(record)
        if finished.done():  # cancelled while it waited for its conflicts
            return result_of(finished)
        self._starting_ids.add(task_id)
        try:
            execution = await self.runners_by_name[record.task_name].start(message, record)
        finally:
            self._starting_ids.discard(task_id)
            self._started[task_id].set_result(None)
        self._executions[task_id] = execution
        record.mark_started()
        self.events.started(record)
        self.history.changed(record)
        self._log.debug(f'task {task_id} ({record.task_name}) from {record.source!r} started')
        self._publish_active_soon()
        execution.outcome.add_done_callback(lambda done: self._settle(task_id, result_of(done)))
        if record.cancel_reason is not None:  # a cancel arrived while the task was starting
            self._cancel_future(record, record.cancel_reason)
        await resolved(self.node, finished)
        return result_of(finished)

    async def _resolve_conflicts(self, record: TaskRecord) -> None:
        conflicts = self.registry.conflicts_of(record.spec, record.task_id)
        if not conflicts:
            return
        self._log.info(
            f'task {record.task_id} ({record.task_name}) cancels conflicting task(s) '
            + ', '.join(f'{c.task_id} ({c.task_name})' for c in conflicts)
        )
        cancels = [self._cancel_future(c, CancelReason.CONFLICT) for c in conflicts]
        await resolved(
            self.node, first_completed([all_completed(cancels), self._finished[record.task_id]])
        )
        if self._finished[record.task_id].done():
            return
        stuck = [c for c, cancel in zip(conflicts, cancels, strict=True) if not cancel.result()]
        if stuck:
            raise TaskRequestError(
                ErrorCode.TASK_START_FAILED,
                'could not cancel conflicting task(s) within their cancel_timeout: '
                + ', '.join(f'{c.task_id} ({c.task_name})' for c in stuck),
            )

    def _settle(self, task_id: str, end: TaskEnd) -> None:
        finished = self._finished.get(task_id)
        if finished is not None and not finished.done():
            finished.set_result(end)

    # ---- cancelling ----------------------------------------------------------------------

    def cancel(self, task_id: str, reason: CancelReason) -> Future:
        """Cancel an active task; the future completes with True once it has ended in time.

        An id that is not active completes True at once (there is nothing left to cancel).
        False means the task did not end within its cancel_timeout and is still running
        (e.g. a service call, which cannot be interrupted): it ends when its server says so.
        """
        record = self.registry.get(task_id)
        if record is None:
            return completed_future(True)
        return self._cancel_future(record, reason)

    def _cancel_future(self, record: TaskRecord, reason: CancelReason) -> Future:
        task_id = record.task_id
        in_flight = self._cancels_in_flight.get(task_id)
        if in_flight is not None:
            return in_flight
        record.request_cancel(reason)
        if self._finished[task_id].done():
            return completed_future(True)
        if record.status is TaskStatus.RECEIVED and task_id not in self._starting_ids:
            self._settle(task_id, TaskEnd(TaskStatus.CANCELED))  # it never started
            return completed_future(True)
        cancelled: Future = Future()
        self._cancels_in_flight[task_id] = cancelled
        self._spawn(
            self._cancel_started(
                record, reason, self._started[task_id], self._finished[task_id], cancelled
            )
        )
        return cancelled

    async def _cancel_started(
        self,
        record: TaskRecord,
        reason: CancelReason,
        started: Future,
        finished: Future,
        cancelled: Future,
    ) -> None:
        """Cancel a task that is starting or running, within its cancel_timeout."""
        task_id = record.task_id
        timeout_sec = record.spec.cancel_timeout_sec
        clock = self.node.get_clock()
        began = clock.now()
        await wait_for(self.node, first_completed([started, finished]), timeout_sec)
        execution = self._executions.get(task_id)
        ok = finished.done()
        if not ok and execution is not None:
            remaining_sec = timeout_sec - (clock.now() - began).nanoseconds / 1e9
            ok = await execution.cancel(remaining_sec) or finished.done()
        if not ok:
            self._log.warning(
                f'task {task_id} ({record.task_name}): cancel ({reason}) did not complete '
                f'within cancel_timeout {timeout_sec} s; the task goes on'
            )
        self._cancels_in_flight.pop(task_id, None)
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
        for record in self.registry:
            self._log.warning(f'task {record.task_id} ({record.task_name}) did not end: {reason}')
            self._settle(record.task_id, TaskEnd(TaskStatus.ERROR, {'error': reason}))
        await wait_for(self.node, self._idle, FORCED_END_TIMEOUT_SEC)
        return False

    # ---- ending ----------------------------------------------------------------------------

    def _finish(self, record: TaskRecord, end: TaskEnd) -> Future[None]:
        """End the task; the future completes once its end is stored and announced."""
        was_active = record.status is TaskStatus.IN_PROGRESS
        record.mark_ended(end.status, end.result, end.error_code)
        self.registry.remove(record.task_id)
        for table in (self._finished, self._started, self._executions):
            table.pop(record.task_id, None)
        if was_active:
            self._ended_unpublished.append(record)
            self._publish_active_soon()
        announced = self._publish_end(record)
        if not len(self.registry) and not self._idle.done():
            self._idle.set_result(None)
        ran_sec = (
            f' after {record.ended_at - record.started_at:.2f} s'
            if record.started_at is not None and record.ended_at is not None
            else ''
        )
        self._log.info(
            f'task {record.task_id} ({record.task_name}) from {record.source!r} ended '
            f'{record.status}{ran_sec}' + (f' ({record.error_code})' if record.error_code else '')
        )
        return announced

    def _publish_end(self, record: TaskRecord) -> Future[None]:
        """Store the task's end; it is announced once committed (see history_writer.py)."""
        return self.history.ended(record)

    def announce_end(self, record: TaskRecord) -> None:
        """ENDED on the event stream and the result on /task_manager/results."""
        self.events.ended(record)
        self._reporter.publish_result(record)

    def _publish_active_soon(self) -> None:
        """Publish active_tasks once the executor has handled what is ready now.

        The changes of one executor turn share one publication: with hundreds of tasks,
        a list per change would cost more than the tasks themselves.
        """
        if not self._publication_pending:
            self._publication_pending = True
            self._spawn(self._publish_active())

    async def _publish_active(self) -> None:
        self._publication_pending = False
        in_progress = self.registry.in_progress()
        if self._ended_unpublished:
            self._reporter.publish_active(in_progress + self._ended_unpublished)
            self._ended_unpublished = []
        self._reporter.publish_active(in_progress)
