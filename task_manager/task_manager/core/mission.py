"""Mission sequencing: subtasks run in order; a failure ends the mission unless skippable."""

import uuid
from dataclasses import dataclass

from task_manager.core.status import CancelReason, ErrorCode, TaskStatus


@dataclass(frozen=True)
class SubtaskRefusal:
    """Why a subtask cannot run (unknown task, bad data): it fails when its turn comes."""

    error_code: ErrorCode
    reason: str


@dataclass
class SubtaskRow:
    """One subtask of a mission and how it went (a row of mission_results)."""

    task_id: str
    task_name: str
    task_data: str
    allow_skipping: bool = False
    status: TaskStatus = TaskStatus.RECEIVED
    """RECEIVED until the subtask has run; never-run subtasks keep it."""
    skipped: bool = False
    refusal: SubtaskRefusal | None = None
    """Set when the subtask is invalid: it fails (or is skipped) without being started."""


@dataclass
class MissionProgress:
    """Where a mission is: which subtask is next, and whether the mission has ended."""

    rows: list[SubtaskRow]
    next_index: int = 0
    failed: bool = False
    cancel_reason: CancelReason | None = None

    @classmethod
    def plan(cls, subtasks: list[tuple[str, str, str, bool]]) -> 'MissionProgress':
        """Rows for (task_id, task_name, task_data, allow_skipping); empty ids generated now."""
        return cls(
            [
                SubtaskRow(task_id or str(uuid.uuid4()), name, data, allow_skipping)
                for task_id, name, data, allow_skipping in subtasks
            ]
        )

    def next_subtask(self) -> SubtaskRow | None:
        """The subtask to run now, or None when the mission is over."""
        if self.failed or self.cancel_reason is not None or self.next_index >= len(self.rows):
            return None
        return self.rows[self.next_index]

    def subtask_ended(self, status: TaskStatus, cancel_reason: CancelReason | None) -> None:
        """Record how the current subtask ended and decide whether the mission goes on.

        A subtask that was pre-empted by a conflicting task ends the mission even when it
        may be skipped: another task has taken over the robot. Other failures of a
        skippable subtask mark it skipped and the mission goes on.
        """
        row = self.rows[self.next_index]
        row.status = status
        self.next_index += 1
        if status is TaskStatus.DONE or self.cancel_reason is not None:
            return
        if row.allow_skipping and cancel_reason is not CancelReason.CONFLICT:
            row.skipped = True
            return
        self.failed = True

    def unskippable_refusals(self) -> list[SubtaskRow]:
        """Invalid subtasks that may not be skipped: the mission must not start."""
        return [row for row in self.rows if row.refusal is not None and not row.allow_skipping]

    def fail_before_start(self) -> None:
        """End the mission before its first subtask: its unskippable invalid subtasks ERROR."""
        for row in self.unskippable_refusals():
            row.status = TaskStatus.ERROR
        self.failed = True

    def cancel(self, reason: CancelReason) -> None:
        if self.cancel_reason is None:
            self.cancel_reason = reason

    @property
    def final_status(self) -> TaskStatus:
        """The mission's end status once next_subtask() is None."""
        if self.cancel_reason is not None:
            return TaskStatus.CANCELED
        return TaskStatus.ERROR if self.failed else TaskStatus.DONE

    def feedback(self, running: bool) -> dict[str, object]:
        """The mission's progress as its feedback: the subtask at its turn and every row.

        `running`: the subtask at `next_index` has started (shown IN_PROGRESS).
        """
        rows = [
            {
                'task_id': row.task_id,
                'task_name': row.task_name,
                'task_status': str(row.status),
                'skipped': row.skipped,
            }
            for row in self.rows
        ]
        current = self.next_subtask()
        if running and current is not None:
            rows[self.next_index]['task_status'] = str(TaskStatus.IN_PROGRESS)
        return {
            'current_index': self.next_index if current is not None else -1,
            'subtasks': rows,
        }

    def duplicate_ids(self) -> list[str]:
        """Subtask ids given more than once in the mission."""
        ids = [row.task_id for row in self.rows]
        return sorted({task_id for task_id in ids if ids.count(task_id) > 1})
