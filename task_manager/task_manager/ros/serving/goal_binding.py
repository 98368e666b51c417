"""Action goals served by the node, bound to the tasks they run."""

import contextlib
import dataclasses
from typing import Any, Protocol

from rclpy.action.server import CancelResponse
from rclpy.node import Node
from rclpy.task import Future

from task_manager.core.status import CancelReason, ErrorCode, TaskStatus
from task_manager.core.task import TaskRecord, TaskRequest
from task_manager.messages.json_codec import TaskDataError, message_from_dict
from task_manager.rclpy_tools.futures import first_completed, resolved, result_of
from task_manager.ros.running.protocols import ActiveRecords, TaskCancelling, TaskRunning


class GoalTasks(TaskRunning, TaskCancelling, ActiveRecords, Protocol):
    """What a goal needs of its task: run it, cancel it, read it."""


@dataclasses.dataclass
class _BoundGoal:
    """A goal whose task is running: its task's id, and whether its client's cancel failed."""

    task_id: str
    cancel_failed: Future[TaskRecord] = dataclasses.field(default_factory=Future)


class GoalTaskBinding:
    """Runs an action goal's task and lets the goal's client cancel it."""

    def __init__(self, node: Node, tasks: GoalTasks) -> None:
        self._node = node
        self._tasks = tasks
        # key: goal id (bytes), value: the goal's task, once admitted
        self._bound_goals: dict[bytes, _BoundGoal] = {}

    async def run(
        self, goal_handle: Any, request: TaskRequest, feedback_type: Any = None
    ) -> TaskRecord:
        """Run the goal's task until the goal has its answer; put the goal in its end state.

        The answer is the task's end, unless the goal's client cancelled it and the cancel
        failed (a service call cannot be interrupted): then the goal ends at once with
        ERROR / task_cancel_failed while the task goes on, and the task's real end is
        published on /task_manager/results when it comes.
        With `feedback_type`, the task's feedback is forwarded to the goal's client.
        """
        goal_key = bytes(goal_handle.goal_id.uuid)
        bound = _BoundGoal('')

        def bind(record: TaskRecord) -> None:
            bound.task_id = record.task_id
            self._bound_goals[goal_key] = bound
            if feedback_type is not None:
                record.feedback_listeners.append(
                    lambda task: _forward_feedback(goal_handle, feedback_type, task.latest_feedback)
                )
            if goal_handle.is_cancel_requested:  # cancelled before its task was admitted
                self._cancel_task(bound)

        node = self._node
        assert node.executor is not None
        # rclpy runs coroutines too, but types create_task for callables only
        task: Future[TaskRecord] = node.executor.create_task(  # type: ignore[call-overload]
            self._tasks.run(request, on_admitted=bind)
        )
        try:
            await resolved(node, first_completed([task, bound.cancel_failed]))
        finally:
            self._bound_goals.pop(goal_key, None)
        record = result_of(task) if task.done() else result_of(bound.cancel_failed)
        finish_goal(goal_handle, record)
        return record

    def cancel_callback(self, goal_handle: Any) -> CancelResponse:
        """Accept a client's cancel of an active goal and start cancelling the goal's task.

        A goal whose task is not admitted yet (its coroutine has not run since the goal was
        accepted) is accepted too: its goal is then CANCELING, and `run` cancels the task as
        it admits it. A cancel is never lost.
        """
        if not goal_handle.is_active:
            return CancelResponse.REJECT
        bound = self._bound_goals.get(bytes(goal_handle.goal_id.uuid))
        if bound is not None:
            self._cancel_task(bound)
        return CancelResponse.ACCEPT

    def _cancel_task(self, bound: _BoundGoal) -> None:
        cancelled = self._tasks.cancel(bound.task_id, CancelReason.CLIENT)
        cancelled.add_done_callback(lambda done: self._on_cancel_done(bound, done))

    def _on_cancel_done(self, bound: _BoundGoal, cancelled: Future[Any]) -> None:
        record = self._tasks.record(bound.task_id)
        if cancelled.result() or record is None or bound.cancel_failed.done():
            return
        timeout_sec = record.spec.cancel_timeout_sec
        bound.cancel_failed.set_result(
            dataclasses.replace(
                record,
                status=TaskStatus.ERROR,
                error_code=ErrorCode.TASK_CANCEL_FAILED,
                result={
                    'error': f'the task did not stop within its cancel_timeout of '
                    f'{timeout_sec} s and is still running; its end will be published '
                    'on /task_manager/results'
                },
            )
        )


def _forward_feedback(
    goal_handle: Any, feedback_type: Any, feedback: dict[str, Any] | None
) -> None:
    if feedback is None or not goal_handle.is_active:
        return
    # feedback of another shape than the interface's has nothing to forward
    with contextlib.suppress(TaskDataError):
        goal_handle.publish_feedback(message_from_dict(feedback_type, feedback))


def finish_goal(goal_handle: Any, record: TaskRecord) -> None:
    """DONE succeeds; CANCELED at the client's request is canceled; the rest is aborted.

    ROS allows "canceled" only for a goal whose client asked for it, so a task cancelled by
    someone else (a conflict, system/cancel_task, system/stop) aborts its goal.
    """
    if record.status is TaskStatus.DONE:
        goal_handle.succeed()
    elif record.status is TaskStatus.CANCELED and goal_handle.is_cancel_requested:
        goal_handle.canceled()
    else:
        goal_handle.abort()
