"""A task's life on its server: its attempts, their timeouts, its cancel, and its end.

An attempt starts the task on its server through the task's runner and tracks it there until
the server says it has ended. An attempt that ends ERROR is followed by another, after its
backoff, while the declaration's retry allows (core/admission/retry.py); the task ends with
the last. A cancel ends a task that has not started at once, and a started one through its
server, within its cancel_timeout. Every end of a task is set in one place, `Attempts.end`;
the task's coroutine in the dispatcher then stores and announces it.
"""

from collections.abc import Callable

from rclpy.node import Node
from rclpy.task import Future

from task_manager.core.admission.decisions import DecisionKind
from task_manager.core.errors import TaskRequestError
from task_manager.core.status import CancelReason, ErrorCode, TaskStatus
from task_manager.core.task import TaskEnd, TaskRecord
from task_manager.rclpy_tools.futures import (
    completed_future,
    first_completed,
    resolved,
    result_of,
    wait_for,
)
from task_manager.rclpy_tools.log import NodeLog
from task_manager.ros.parking_executor import spawn
from task_manager.ros.recording.task_changes import TaskChange, TaskChanges
from task_manager.ros.running.deadline_timer import Deadline, DeadlineTimer
from task_manager.ros.running.execution import Execution, TaskCatalog
from task_manager.ros.running.task_run import TaskRun


def _label(run: TaskRun) -> str:
    return f'task {run.task_id} ({run.record.task_name})'


def _complete(future: Future[None]) -> None:
    if not future.done():
        future.set_result(None)


class Attempts:
    """Runs each admitted task on its server, attempt after attempt, until it ends."""

    def __init__(
        self,
        node: Node,
        catalog: TaskCatalog,
        changes: TaskChanges,
        timer: DeadlineTimer,
    ) -> None:
        self._node = node
        self._log = NodeLog.of(node)
        self._catalog = catalog
        self._changes = changes
        self._timer = timer
        self._closing = False

    def close(self) -> None:
        """Plan no further attempt (the node is shutting down)."""
        self._closing = True

    # ---- the attempts ---------------------------------------------------------------------

    async def run(self, run: TaskRun) -> TaskEnd:
        """Attempt the task until it ends; its end."""
        while not run.finished.done():
            again: Future[None] = Future()
            run.next_attempt = again
            await self._attempt(run)
            await resolved(self._node, first_completed([run.finished, again]))
        return result_of(run.finished)

    async def _attempt(self, run: TaskRun) -> None:
        """Start the task on its server and track it there; a start that fails ends it."""
        try:
            execution = await self.start_on_server(run)
        except TaskRequestError as error:
            self._start_failed(run, error)
            return
        self.track(run, execution, lambda: self._began(run, execution))

    def _start_failed(self, run: TaskRun, error: TaskRequestError) -> None:
        record = run.record
        if record.cancel_reason is not None:
            # Cancelled before its server accepted it: it did not run, as its canceller asked;
            # why it could not have started is kept in its result.
            self.end(run, TaskEnd(TaskStatus.CANCELED, {'error': str(error)}))
            return
        self._attempt_ended(run, TaskEnd(TaskStatus.ERROR, {'error': str(error)}, error.error_code))
        if run.finished.done():
            self._log.warning(f'{_label(run)} failed: {error}')

    async def start_on_server(self, run: TaskRun) -> Execution:
        """Start the task on its server (again, on resume); raises TaskRequestError."""
        run.starting = True
        run.started = Future()
        runner = self._catalog.get(run.record.task_name)
        assert runner is not None, 'an admitted task has its runner'
        try:
            return await runner.start(run.message, run.record)
        finally:
            run.starting = False
            run.started.set_result(None)

    def track(self, run: TaskRun, execution: Execution, steps: Callable[[], None]) -> None:
        """Carry out `steps`, which track a task now running on its server (mark it started,
        attach its execution, arm its timeouts). Should one fail, the goal must not run on
        untracked: it is cancelled, and the task ends ERROR once its server says it has ended,
        or once its cancel_timeout has passed (then its result says the goal may still run)."""
        try:
            steps()
        except Exception as error:  # the callback boundary: a bug of ours must not free a robot
            self._log.error(
                f'{_label(run)} could not be tracked once started: {error!r}; '
                'cancelling it on its server'
            )
            run.execution = None  # its end is the withdrawal's, not the server's result
            spawn(self._node, self._withdraw(run, execution, error))

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
        self.end(run, TaskEnd(TaskStatus.ERROR, {'error': reason}, ErrorCode.TASK_START_FAILED))

    def _began(self, run: TaskRun, execution: Execution) -> None:
        """An attempt runs on its server: the task is IN_PROGRESS (once) and its timeouts armed."""
        record = run.record
        if not record.status.is_started:
            record.mark_started()
            decided = record.decisions[-1].reason if record.decisions else ''
            reason = decided if run.dequeued or run.preemptions else ''
            self._changes.changed(record, TaskChange.STARTED, reason)
            self._log.debug(f'{_label(run)} from {record.source!r} started')
        self.attach(run, execution)
        self.arm_timeouts(run)

    def attach(self, run: TaskRun, execution: Execution) -> None:
        """Track the task's execution on its server; its end is the attempt's end."""
        run.execution = execution
        execution.outcome.add_done_callback(lambda done: self._on_outcome(run, execution, done))
        if run.record.cancel_reason is not None:  # a cancel arrived while the task was starting
            self.cancel(run, run.record.cancel_reason)

    def _on_outcome(self, run: TaskRun, execution: Execution, done: Future[TaskEnd]) -> None:
        end = result_of(done)
        if run.execution is not execution:  # a goal ended by a pause, replaced on resume
            return
        if run.pausing and end.status is TaskStatus.CANCELED and run.record.cancel_reason is None:
            return  # the pause's own cancel: the task goes on, paused
        self._attempt_ended(run, end)

    def _attempt_ended(self, run: TaskRun, end: TaskEnd) -> None:
        """The task ends with its attempt, or another attempt follows after its backoff."""
        self._timer.clear(run.task_id, Deadline.RUN, Deadline.FEEDBACK)
        if run.timeout_reason:  # the server's result, whole: the reason is a decision
            end = TaskEnd(TaskStatus.ERROR, end.result, ErrorCode.TIMEOUT)
        delay_sec = self._retry_delay(run, end)
        if delay_sec is None:
            self.end(run, end)
            return
        again = run.next_attempt
        self._timer.set(run.task_id, Deadline.RETRY, delay_sec, lambda: _complete(again))

    def end(self, run: TaskRun, end: TaskEnd) -> None:
        """End the task with `end`, unless it has ended already (the first end wins)."""
        if not run.finished.done():
            run.finished.set_result(end)

    # ---- retries ---------------------------------------------------------------------------

    def _retry_delay(self, run: TaskRun, end: TaskEnd) -> float | None:
        """Plan the next attempt after an ERROR, if the declaration's retry allows it: the
        seconds before it starts; None when the task ends with `end`."""
        record = run.record
        policy = record.spec.retry
        timed_out = end.error_code is ErrorCode.TIMEOUT and bool(run.timeout_reason)
        cancelled = record.cancel_reason is not None and not timed_out
        if end.status is not TaskStatus.ERROR or cancelled or self._closing:
            return None
        what = str(end.error_code) or 'its server failed it'
        if not policy.retries(record.attempt, end.error_code):
            if policy.max_attempts > 1:
                record.note(DecisionKind.RETRY, _no_retry_reason(record, what))
            return None
        delay_sec = policy.delay_sec(record.attempt)
        reason = (
            f'retry: attempt {record.attempt} of {policy.max_attempts} ended ERROR ({what}); '
            f'attempt {record.attempt + 1} in {delay_sec:g} s'
        )
        record.attempt += 1
        record.cancel_reason = None
        run.timeout_reason = ''
        run.execution = None
        record.note(DecisionKind.RETRY, reason)
        self._log.info(f'{_label(run)}: {reason}')
        self._changes.changed(record, TaskChange.DECIDED, reason)
        return delay_sec

    # ---- timeouts of a running attempt -----------------------------------------------------

    def arm_timeouts(self, run: TaskRun) -> None:
        """Arm the attempt's timeout_sec and feedback_timeout_sec."""
        record = run.record
        timeout_sec = run.options.timeout_sec or record.spec.timeout_sec
        if timeout_sec:
            reason = f'timed out: ran {timeout_sec:g} s (timeout_sec)'
            self._timer.set(
                record.task_id, Deadline.RUN, timeout_sec, lambda: self._timed_out(run, reason)
            )
        stall_sec = run.options.feedback_timeout_sec or record.spec.feedback_timeout_sec
        if stall_sec and not run.watches_feedback:
            run.watches_feedback = True
            record.feedback_listeners.append(lambda _: self._feedback_seen(run, stall_sec))
        if stall_sec:
            self._feedback_seen(run, stall_sec)

    def _feedback_seen(self, run: TaskRun, stall_sec: float) -> None:
        if run.execution is None or run.finished.done():
            return
        reason = f'timed out: stalled, no feedback for {stall_sec:g} s (feedback_timeout_sec)'
        self._timer.set(
            run.task_id, Deadline.FEEDBACK, stall_sec, lambda: self._timed_out(run, reason)
        )

    def _timed_out(self, run: TaskRun, reason: str) -> None:
        if run.finished.done() or run.timeout_reason:
            return
        run.timeout_reason = reason
        run.record.note(DecisionKind.TIMEOUT, reason)
        self._log.warning(f'{_label(run)} {reason}')
        self.cancel(run, CancelReason.TIMEOUT)

    # ---- cancelling ------------------------------------------------------------------------

    def cancel(self, run: TaskRun, reason: CancelReason) -> Future[bool]:
        """Cancel the task; the future completes with True once it has ended in time.

        False means the task did not end within its cancel_timeout and is still running
        (e.g. a service call, which cannot be interrupted): it ends when its server says so.
        """
        if run.cancel_in_flight is not None:
            return run.cancel_in_flight
        run.record.request_cancel(reason)
        if run.finished.done():
            return completed_future(True)
        if run.execution is None and not run.starting:  # not started yet, or paused by restart
            self.end(run, TaskEnd(TaskStatus.CANCELED))
            return completed_future(True)
        cancelled: Future[bool] = Future()
        run.cancel_in_flight = cancelled
        spawn(self._node, self._cancel_started(run, reason, cancelled))
        return cancelled

    async def _cancel_started(
        self, run: TaskRun, reason: CancelReason, cancelled: Future[bool]
    ) -> None:
        """Cancel a task that is starting or running, within its cancel_timeout."""
        record = run.record
        timeout_sec = record.spec.cancel_timeout_sec
        clock = self._node.get_clock()
        began = clock.now()
        await wait_for(self._node, first_completed([run.started, run.finished]), timeout_sec)
        execution = run.execution
        ok = run.finished.done()
        if not ok and execution is not None:
            remaining_sec = timeout_sec - (clock.now() - began).nanoseconds / 1e9
            ok = await execution.cancel(remaining_sec) or run.finished.done()
        if not ok:
            self._log.warning(
                f'{_label(run)}: cancel ({reason}) did not complete within cancel_timeout '
                f'{timeout_sec} s; the task goes on'
            )
        run.cancel_in_flight = None
        cancelled.set_result(ok)


def _no_retry_reason(record: TaskRecord, what: str) -> str:
    policy = record.spec.retry
    if record.attempt >= policy.max_attempts:
        return (
            f'gave up: attempt {record.attempt} of {policy.max_attempts} ended ERROR '
            f'({what}); no attempt left'
        )
    codes = ', '.join(policy.on_error_codes)
    return f'no retry: ended ERROR ({what}), which is not among on_error_codes ({codes})'
