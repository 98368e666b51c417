"""One admitted task's run state, held in the table of runs from admission until the task ends."""

from dataclasses import dataclass, field
from typing import Any, TypeAlias

from rclpy.task import Future

from task_manager.core.admission.arbiter import Preemption
from task_manager.core.admission.options import RequestOptions
from task_manager.core.registry import TaskRegistry
from task_manager.core.status import TaskStatus
from task_manager.core.task import TaskEnd, TaskRecord
from task_manager.core.task_spec import TaskSpec
from task_manager.ros.running.execution import Execution


@dataclass(eq=False)
class TaskRun:
    """A task's futures, its execution on its server, and its cancel and pause in flight.

    One object per task (not a table per attribute), so that a task's state cannot drift
    apart across maps as features add to it.
    """

    record: TaskRecord
    message: Any
    """The parsed goal/request: sent again when a `pause: restart` task resumes."""
    finished: Future[TaskEnd] = field(default_factory=Future)
    """Completes with the task's end (the first writer wins: see Attempts.end)."""
    next_attempt: Future[None] = field(default_factory=Future)
    """Completes once the attempt running now has ended ERROR and its retry's backoff passed."""
    started: Future[None] = field(default_factory=Future)
    """Completes once the current start on the server has succeeded or failed."""
    execution: Execution | None = None
    """The task on its server; None before it starts and while it is paused by restart."""
    starting: bool = False
    """A start (or a restart on resume) on the server is in flight."""
    cancel_in_flight: Future[bool] | None = None
    """Completes with True when the cancel in flight ended the task in time."""
    pausing: bool = False
    """A pause is cancelling the server's goal: that goal's CANCELED end is not the task's."""
    options: RequestOptions = field(default_factory=RequestOptions)
    """The request's own admission options (priority, on_conflict, timeouts)."""
    dequeued: Future[None] | None = None
    """While it is (or was) queued: completes when its turn comes."""
    preemptions: tuple[Preemption, ...] = ()
    """The tasks it must cancel before it starts, as the arbiter decided."""
    preempted: bool = False
    """Its pre-emptions were carried out (the victims were asked to cancel)."""
    timeout_reason: str = ''
    """Set when one of its running timeouts fired: its end is ERROR / timeout."""
    watches_feedback: bool = False
    """Its feedback_timeout_sec listener is in place (added once, for every attempt)."""

    @property
    def task_id(self) -> str:
        return self.record.task_id

    @property
    def spec(self) -> TaskSpec:
        return self.record.spec

    @property
    def status(self) -> TaskStatus:
        return self.record.status


Runs: TypeAlias = TaskRegistry[TaskRun]
"""The one table of the admitted tasks: each one's run, by id, in the order they came."""
