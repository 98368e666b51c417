"""Carries out the arbiter's decisions on ROS: the queue's waits and its timeout, priorities.

The decisions themselves are made in core/admission (no rclpy); this module keeps the
arbiter in step with the admitted tasks, wakes a queued task when its turn comes, and cancels
the tasks it pre-empts. The queue's timeouts are on the one DeadlineTimer: a queued task costs
no thread and no timer of its own.
"""

import time
from collections.abc import Mapping

from rclpy.node import Node
from rclpy.task import Future

from task_manager.core.admission.arbiter import Arbiter, Decision, Verdict
from task_manager.core.admission.claims import Claim, implied_resources
from task_manager.core.admission.decisions import DecisionKind
from task_manager.core.admission.options import RequestOptions
from task_manager.core.admission.priority import effective_priority
from task_manager.core.errors import TaskRequestError
from task_manager.core.status import CancelReason, ErrorCode, TaskStatus
from task_manager.core.task import TaskEnd, TaskRecord, TaskRequest
from task_manager.rclpy_tools.futures import all_completed, first_completed, resolved
from task_manager.rclpy_tools.log import NodeLog
from task_manager.ros.recording.task_changes import TaskChange, TaskChanges
from task_manager.ros.running.attempts import Attempts
from task_manager.ros.running.deadline_timer import Deadline, DeadlineTimer
from task_manager.ros.running.task_run import Runs, TaskRun


class AdmissionControl:
    """The arbiter of the node's tasks: who runs, who waits, who is pre-empted."""

    def __init__(
        self,
        node: Node,
        runs: Runs,
        changes: TaskChanges,
        attempts: Attempts,
        timer: DeadlineTimer,
        max_queued: int,
        source_priorities: Mapping[str, int],
    ) -> None:
        self._node = node
        self._log = NodeLog.of(node)
        self._runs = runs
        self._changes = changes
        self._attempts = attempts
        self._timer = timer
        self.arbiter = Arbiter(max_queued)
        self.source_priorities = dict(source_priorities)

    # ---- admission ------------------------------------------------------------------------------

    def priority_of(self, request: TaskRequest, record: TaskRecord) -> int:
        """The request's own priority, or the declared one plus its source's; a subtask
        has at least its mission's."""
        priority = effective_priority(
            record.spec.priority, record.source, self.source_priorities, request.options.priority
        )
        parent = self._runs.get(request.parent_id)
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
        self._changes.changed(record, TaskChange.QUEUED, decision.reason)
        self._update_positions()
        timeout_sec = run.options.queue_timeout_sec or record.spec.queue_timeout_sec
        if timeout_sec:
            reason = f'timed out: waited {timeout_sec:g} s in the queue (queue_timeout_sec)'
            self._timer.set(
                record.task_id,
                Deadline.QUEUE,
                timeout_sec,
                lambda: self._queue_timeout(run, reason),
            )

    async def turn(self, run: TaskRun) -> None:
        """Wait until the task's turn has come: out of the queue, if it waits there, and the
        tasks it pre-empts cancelled (TaskRequestError if one does not end within its
        cancel_timeout). Returns early once the task has ended meanwhile (cancelled)."""
        if run.dequeued is not None and not run.finished.done():
            await resolved(self._node, first_completed([run.dequeued, run.finished]))
        if not run.finished.done():
            await self._preempt(run)

    async def _preempt(self, run: TaskRun) -> None:
        record = run.record
        run.preempted = True
        conflicts: list[TaskRun] = []
        for preemption in run.preemptions:
            victim = self._runs.get(preemption.victim.task_id)
            if victim is not None and not victim.finished.done():
                victim.record.note(DecisionKind.PREEMPTED, preemption.reason)
                conflicts.append(victim)
        claim = self.arbiter.holders.get(record.task_id)
        for ending in self.arbiter.still_ending(claim) if claim is not None else []:
            other = self._runs.get(ending.task_id)
            if other is not None and other not in conflicts:
                conflicts.append(other)
        if not conflicts:
            return
        self._log.info(
            f'task {record.task_id} ({record.task_name}) cancels conflicting task(s) '
            + ', '.join(f'{c.task_id} ({c.record.task_name})' for c in conflicts)
        )
        cancels = [self._attempts.cancel(c, CancelReason.CONFLICT) for c in conflicts]
        await resolved(self._node, first_completed([all_completed(cancels), run.finished]))
        if run.finished.done():
            return
        stuck = [c for c, cancel in zip(conflicts, cancels, strict=True) if not cancel.result()]
        if stuck:
            raise TaskRequestError(
                ErrorCode.TASK_START_FAILED,
                'could not cancel conflicting task(s) within their cancel_timeout: '
                + ', '.join(f'{c.task_id} ({c.record.task_name})' for c in stuck),
            )

    def released(self, run: TaskRun) -> None:
        """The task ended: its resources go to the queued tasks whose turn it is."""
        task_id = run.task_id
        self._timer.clear(task_id)
        for preemption in run.preemptions if not run.preempted else ():
            victim = self._runs.get(preemption.victim.task_id)
            if victim is None or victim.finished.done():
                continue
            if not self.arbiter.reinstate(victim.task_id):  # never pre-empted after all...
                # ...but another task took one of its resources meanwhile: it must not run on
                # holding nothing beside that task, so it is pre-empted as decided
                reason = f'{preemption.reason}, which ended first; its resources were taken'
                victim.record.note(DecisionKind.PREEMPTED, reason)
                self._attempts.cancel(victim, CancelReason.CONFLICT)
        was_queued = self.arbiter.is_queued(task_id)
        started = self.arbiter.release(task_id)
        self._start_queued(started)
        if was_queued or started:  # the queue moved: every waiting task's place changes
            self._update_positions()

    def reprioritize(self, task_id: str, priority: int, source: str) -> str:
        """Give an active task a new priority; '' when done, else why not."""
        run = self._runs.get(task_id)
        if run is None:
            return f'task {task_id!r} is not active'
        before = run.record.priority
        started = self.arbiter.reprioritize(task_id, priority)
        run.record.priority = priority
        reason = f'priority {before} -> {priority}, by {source}'
        run.record.note(DecisionKind.REPRIORITIZED, reason)
        self._changes.changed(run.record, TaskChange.DECIDED, reason)
        self._start_queued(started or [])
        self._update_positions()
        return ''

    def _start_queued(self, claims: list[Claim]) -> None:
        for claim in claims:
            run = self._runs.get(claim.task_id)
            if run is None or run.dequeued is None or run.dequeued.done():
                continue
            self._timer.clear(claim.task_id, Deadline.QUEUE)
            waited_sec = time.time() - run.record.received_at
            run.record.note(DecisionKind.STARTED, f'its turn came after {waited_sec:.1f} s queued')
            run.dequeued.set_result(None)

    def _update_positions(self) -> None:
        for position, claim in enumerate(self.arbiter.queued, start=1):
            run = self._runs.get(claim.task_id)
            if run is not None:
                run.record.queue_position = position
        self._changes.places_changed()

    def _queue_timeout(self, run: TaskRun, reason: str) -> None:
        record = run.record
        if run.finished.done() or record.status is not TaskStatus.QUEUED:
            return
        record.note(DecisionKind.TIMEOUT, reason)
        self._attempts.end(run, TaskEnd(TaskStatus.ERROR, {'error': reason}, ErrorCode.TIMEOUT))
