"""Carries out the arbiter's decisions on ROS: the queue's waits, timeouts and retries.

The decisions themselves are made in core/admission (no rclpy); this module keeps the
arbiter in step with the dispatcher's tasks, wakes a queued task when its turn comes, and
runs every timeout and retry backoff on one timer armed for the earliest deadline: a queued
or running task costs no thread and no timer of its own.
"""

import time
from collections.abc import Mapping
from typing import TYPE_CHECKING

from rclpy.task import Future

from task_manager.core.admission.arbiter import Arbiter, Decision, Verdict
from task_manager.core.admission.claims import Claim, implied_resources
from task_manager.core.admission.deadlines import Deadlines
from task_manager.core.admission.decisions import DecisionKind
from task_manager.core.admission.options import RequestOptions
from task_manager.core.admission.priority import effective_priority
from task_manager.core.errors import TaskRequestError
from task_manager.core.status import CancelReason, ErrorCode, TaskStatus
from task_manager.core.task import TaskEnd, TaskRecord, TaskRequest
from task_manager.rclpy_tools.cleanup import destroy_timer
from task_manager.ros.running.task_run import TaskRun

if TYPE_CHECKING:
    from task_manager.ros.running.dispatcher import TaskDispatcher

_IDLE_PERIOD_SEC = 3600.0
_RUN, _QUEUE, _FEEDBACK, _RETRY = 'run', 'queue', 'feedback', 'retry'


class AdmissionControl:
    """The arbiter of the node's tasks, and the deadlines of their timeouts and retries."""

    def __init__(
        self,
        dispatcher: 'TaskDispatcher',
        max_queued: int,
        source_priorities: Mapping[str, int],
    ) -> None:
        self._dispatcher = dispatcher
        self._node = dispatcher.node
        self.arbiter = Arbiter(max_queued)
        self.source_priorities = dict(source_priorities)
        self._deadlines = Deadlines()
        self._armed_at: float | None = None
        self._timer = self._node.create_timer(_IDLE_PERIOD_SEC, self._on_timer)
        self._timer.cancel()

    def close(self) -> None:
        destroy_timer(self._node, self._timer)

    # ---- admission ------------------------------------------------------------------------------

    def priority_of(self, request: TaskRequest, record: TaskRecord) -> int:
        """The request's own priority, or the declared one plus its source's; a subtask
        has at least its mission's."""
        priority = effective_priority(
            record.spec.priority, record.source, self.source_priorities, request.options.priority
        )
        parent = self._dispatcher.runs_by_id.get(request.parent_id)
        return max(priority, parent.record.priority) if parent is not None else priority

    def decide(
        self, record: TaskRecord, options: RequestOptions, extra: frozenset[str]
    ) -> Decision:
        """The arbiter's verdict on a new task; `extra`: resources its subtasks will hold."""
        spec = record.spec
        claim = Claim(
            record.task_id,
            record.task_name,
            implied_resources(spec.task_name, spec.resources, spec.blocking, spec.reentrant)
            | extra,
            record.priority,
            record.parent_id,
        )
        on_conflict = options.on_conflict or spec.on_conflict
        decision = self.arbiter.decide(claim, on_conflict)
        if decision.verdict is Verdict.REFUSE:
            record.note(DecisionKind.REFUSED, decision.reason)
        elif decision.preemptions:
            record.note(DecisionKind.STARTED, decision.reason)
        return decision

    def queue(self, run: TaskRun, decision: Decision) -> None:
        """The task waits in the queue: QUEUED, its event, and its queue timeout."""
        record = run.record
        run.dequeued = Future()
        record.mark_queued(decision.position)
        record.note(DecisionKind.QUEUED, decision.reason)
        self._dispatcher.events.queued(record, decision.reason)
        self._dispatcher.history.changed(record)
        self._update_positions()
        timeout_sec = run.options.queue_timeout_sec or record.spec.queue_timeout_sec
        if timeout_sec:
            reason = f'timed out: waited {timeout_sec:g} s in the queue (queue_timeout_sec)'
            self._set(record.task_id, _QUEUE, timeout_sec, lambda: self._queue_timeout(run, reason))

    def released(self, run: TaskRun) -> None:
        """The task ended: its resources go to the queued tasks whose turn it is."""
        task_id = run.task_id
        for key in (_RUN, _QUEUE, _FEEDBACK, _RETRY):
            self._deadlines.clear((task_id, key))
        for preemption in run.preemptions if not run.preempted else ():
            victim = self._dispatcher.runs_by_id.get(preemption.victim.task_id)
            if victim is None or victim.finished.done():
                continue
            if not self.arbiter.reinstate(victim.task_id):  # never pre-empted after all...
                # ...but another task took one of its resources meanwhile: it must not run on
                # holding nothing beside that task, so it is pre-empted as decided
                reason = f'{preemption.reason}, which ended first; its resources were taken'
                victim.record.note(DecisionKind.PREEMPTED, reason)
                self._dispatcher.cancel(victim.task_id, CancelReason.CONFLICT)
        was_queued = self.arbiter.is_queued(task_id)
        started = self.arbiter.release(task_id)
        self._start_queued(started)
        if was_queued or started:  # the queue moved: every waiting task's place changes
            self._update_positions()

    def reprioritize(self, task_id: str, priority: int, source: str) -> str:
        """Give an active task a new priority; '' when done, else why not."""
        run = self._dispatcher.runs_by_id.get(task_id)
        if run is None:
            return f'task {task_id!r} is not active'
        before = run.record.priority
        started = self.arbiter.reprioritize(task_id, priority)
        run.record.priority = priority
        reason = f'priority {before} -> {priority}, by {source}'
        run.record.note(DecisionKind.REPRIORITIZED, reason)
        self._dispatcher.events.decided(run.record, reason)
        self._dispatcher.history.changed(run.record)
        self._start_queued(started or [])
        self._update_positions()
        return ''

    def _start_queued(self, claims: list[Claim]) -> None:
        for claim in claims:
            run = self._dispatcher.runs_by_id.get(claim.task_id)
            if run is None or run.dequeued is None or run.dequeued.done():
                continue
            self._deadlines.clear((claim.task_id, _QUEUE))
            waited_sec = time.time() - run.record.received_at
            run.record.note(DecisionKind.STARTED, f'its turn came after {waited_sec:.1f} s queued')
            run.dequeued.set_result(None)

    def _update_positions(self) -> None:
        for position, claim in enumerate(self.arbiter.queued, start=1):
            run = self._dispatcher.runs_by_id.get(claim.task_id)
            if run is not None:
                run.record.queue_position = position
        self._dispatcher.publish_active_soon()

    def _queue_timeout(self, run: TaskRun, reason: str) -> None:
        record = run.record
        if run.finished.done() or record.status is not TaskStatus.QUEUED:
            return
        record.note(DecisionKind.TIMEOUT, reason)
        run.settle(TaskEnd(TaskStatus.ERROR, {'error': reason}, ErrorCode.TIMEOUT))

    # ---- timeouts of a running attempt ---------------------------------------------------------

    def attempt_started(self, run: TaskRun) -> None:
        """Arm the attempt's timeout_sec and feedback_timeout_sec."""
        record = run.record
        timeout_sec = run.options.timeout_sec or record.spec.timeout_sec
        if timeout_sec:
            reason = f'timed out: ran {timeout_sec:g} s (timeout_sec)'
            self._set(record.task_id, _RUN, timeout_sec, lambda: self._timed_out(run, reason))
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
        self._set(run.task_id, _FEEDBACK, stall_sec, lambda: self._timed_out(run, reason))

    def _timed_out(self, run: TaskRun, reason: str) -> None:
        if run.finished.done() or run.timeout_reason:
            return
        run.timeout_reason = reason
        run.record.note(DecisionKind.TIMEOUT, reason)
        self._dispatcher.log.warning(f'task {run.task_id} ({run.record.task_name}) {reason}')
        self._dispatcher.cancel(run.task_id, CancelReason.TIMEOUT)

    def attempt_end(self, run: TaskRun, end: TaskEnd) -> TaskEnd | None:
        """How an attempt's end ends the task: None when another attempt follows."""
        self._deadlines.clear((run.task_id, _RUN))
        self._deadlines.clear((run.task_id, _FEEDBACK))
        if run.timeout_reason:  # the server's result, whole: the reason is a decision
            end = TaskEnd(TaskStatus.ERROR, end.result, ErrorCode.TIMEOUT)
        if self._retry(run, end):
            return None
        return end

    # ---- retries -------------------------------------------------------------------------------

    def _retry(self, run: TaskRun, end: TaskEnd) -> bool:
        """Plan the next attempt after an ERROR, if the declaration's retry allows it."""
        record = run.record
        policy = record.spec.retry
        timed_out = end.error_code is ErrorCode.TIMEOUT and bool(run.timeout_reason)
        cancelled = record.cancel_reason is not None and not timed_out
        if end.status is not TaskStatus.ERROR or cancelled or self._dispatcher.closing:
            return False
        what = str(end.error_code) or 'its server failed it'
        if not policy.retries(record.attempt, end.error_code):
            if policy.max_attempts > 1:
                record.note(DecisionKind.RETRY, self._no_retry_reason(record, what))
            return False
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
        self._dispatcher.log.info(f'task {record.task_id} ({record.task_name}): {reason}')
        self._dispatcher.events.decided(record, reason)
        self._dispatcher.history.changed(record)
        self._set(
            record.task_id, _RETRY, delay_sec, lambda: self._dispatcher.spawn(self._again(run))
        )
        return True

    @staticmethod
    def _no_retry_reason(record: TaskRecord, what: str) -> str:
        policy = record.spec.retry
        if record.attempt >= policy.max_attempts:
            return (
                f'gave up: attempt {record.attempt} of {policy.max_attempts} ended ERROR '
                f'({what}); no attempt left'
            )
        codes = ', '.join(policy.on_error_codes)
        return f'no retry: ended ERROR ({what}), which is not among on_error_codes ({codes})'

    async def _again(self, run: TaskRun) -> None:
        if run.finished.done():
            return
        try:
            execution = await self._dispatcher.start_on_server(run)
        except TaskRequestError as error:
            end = TaskEnd(TaskStatus.ERROR, {'error': str(error)}, error.error_code)
            final = self.attempt_end(run, end)
            if final is not None:
                run.settle(final)
            return
        self._dispatcher.track(run, execution, lambda: self._dispatcher.began(run, execution))

    # ---- the one timer ---------------------------------------------------------------------

    def _set(self, task_id: str, what: str, delay_sec: float, action: object) -> None:
        at = time.monotonic() + delay_sec
        self._deadlines.set((task_id, what), at, action)  # type: ignore[arg-type]
        if self._armed_at is None or at < self._armed_at:
            self._arm()

    def _arm(self) -> None:
        at = self._deadlines.next_at()
        self._armed_at = at
        if at is None:
            self._timer.cancel()
            return
        # at most an hour: a later deadline is armed again when the timer finds nothing due, and
        # no delay can overflow rcl's signed 64-bit nanoseconds or leave the timer always due
        delay_sec = at - time.monotonic()
        if not delay_sec < _IDLE_PERIOD_SEC:  # NaN too
            delay_sec = _IDLE_PERIOD_SEC
        self._timer.timer_period_ns = max(int(delay_sec * 1e9), 1)
        self._timer.reset()

    def _on_timer(self) -> None:
        for action in self._deadlines.pop_due(time.monotonic()):
            action()
        self._arm()
