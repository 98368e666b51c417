"""system/confirm: wait for an operator's answer (core/confirmation.py decides how it ends).

A waiting confirmation holds two timers (its feedback and its timeout) and no thread; the
answers come through /task_manager/confirm_task (ConfirmTask), served by the node.
"""

import sqlite3
from typing import Any

from rclpy.node import Node
from task_manager_msgs.action import Confirm
from task_manager_msgs.srv import ConfirmTask

from task_manager.core.confirmation import (
    Answer,
    AnswerRefusal,
    ConfirmGoal,
    OnTimeout,
    answer_problem,
    end_of_answer,
    end_of_timeout,
    feedback,
    goal_problem,
    not_found_reason,
    not_waiting_reason,
)
from task_manager.core.history.store import HistoryQuery, TaskHistory
from task_manager.core.status import TaskStatus
from task_manager.core.system_tasks import CONFIRM_SPEC
from task_manager.core.task import TaskEnd, TaskRecord
from task_manager.core.text.request_text import loggable
from task_manager.messages.json_codec import TaskDataError, message_from_json
from task_manager.rclpy_tools.log import NodeLog
from task_manager.ros.running.execution import TaskRunner
from task_manager.ros.running.protocols import ActiveRecords
from task_manager.ros.system.timed_execution import TimedExecution

ANSWERS_KEPT = 1000
"""The latest answers taken, so that one asked again (its reply was lost) is taken again."""


class ConfirmExecution(TimedExecution):
    """A confirmation waiting for its answer, its timeout or a cancel."""

    def __init__(self, node: Node, goal: ConfirmGoal, record: TaskRecord) -> None:
        self._goal = goal
        super().__init__(node, record, goal.timeout_sec)

    @property
    def waiting(self) -> bool:
        return not self.outcome.done()

    def feedback_at(self, elapsed_sec: float) -> dict[str, Any]:
        return feedback(self._goal, elapsed_sec)

    def at_deadline(self) -> TaskEnd:
        return end_of_timeout(self._goal)

    def answer(self, answer: Answer) -> None:
        self.end(end_of_answer(answer))

    async def cancel(self, timeout_sec: float) -> bool:
        self.end(TaskEnd(TaskStatus.CANCELED, {}))
        return True


class ConfirmRunner(TaskRunner):
    """Starts confirmations and takes their answers; several may wait at once."""

    spec = CONFIRM_SPEC

    def __init__(self, node: Node, active: ActiveRecords, history: TaskHistory) -> None:
        self._node = node
        self._active = active
        self._history = history
        # key: task id, value: its confirmation, while it waits
        self._waiting: dict[str, ConfirmExecution] = {}
        # key: task id, value: the answer it took (the latest ANSWERS_KEPT, oldest first)
        self._taken: dict[str, Answer] = {}

    def parse(self, task_data: str, task_id: str) -> ConfirmGoal:
        message = message_from_json(Confirm.Goal, task_data)
        if problem := goal_problem(message.prompt, message.timeout_sec, message.on_timeout):
            raise TaskDataError(*problem)
        return ConfirmGoal(message.prompt, message.timeout_sec, OnTimeout(message.on_timeout))

    async def start(self, goal: ConfirmGoal, record: TaskRecord) -> ConfirmExecution:
        execution = ConfirmExecution(self._node, goal, record)
        self._waiting[record.task_id] = execution
        execution.outcome.add_done_callback(lambda _: self._ended(record.task_id))
        return execution

    def _ended(self, task_id: str) -> None:
        self._waiting.pop(task_id, None)

    def answer_service(
        self, request: ConfirmTask.Request, response: ConfirmTask.Response
    ) -> ConfirmTask.Response:
        """/task_manager/confirm_task: the task ends with the answer, or why it cannot."""
        answer = Answer(request.reject, request.source, request.comment)
        refusal = self._refusal(request.task_id, answer)
        if refusal is not None and self._taken.get(request.task_id) == answer:
            response.success = True  # asked again, its reply lost: the answer it took
            return response
        if refusal is not None:
            response.error_code, response.message = refusal
            NodeLog.of(self._node).warning(
                f'answer to {loggable(request.task_id)} from {loggable(answer.by)!r} not taken: '
                f'{loggable(response.message, 300)}'
            )
            return response
        verb = 'rejected' if answer.reject else 'confirmed'
        NodeLog.of(self._node).info(
            f'task {request.task_id} ({CONFIRM_SPEC.task_name}) {verb} by {answer.by!r}'
        )
        self._waiting[request.task_id].answer(answer)
        self._remember(request.task_id, answer)
        response.success = True
        return response

    def _remember(self, task_id: str, answer: Answer) -> None:
        self._taken.pop(task_id, None)
        self._taken[task_id] = answer
        if len(self._taken) > ANSWERS_KEPT:
            del self._taken[next(iter(self._taken))]

    def _refusal(self, task_id: str, answer: Answer) -> tuple[str, str] | None:
        """(error_code, message) when the answer cannot be taken; None when it can."""
        if (execution := self._waiting.get(task_id)) is not None and execution.waiting:
            problem = answer_problem(answer)
            return None if problem is None else (AnswerRefusal.INVALID_REQUEST, problem)
        if (record := self._active.record(task_id)) is not None:
            reason = not_waiting_reason(task_id, record.task_name, record.status)
            return AnswerRefusal.NOT_WAITING, reason
        stored = self._stored(task_id)
        if stored is None:
            return AnswerRefusal.NOT_FOUND, not_found_reason(task_id)
        return AnswerRefusal.NOT_WAITING, not_waiting_reason(task_id, *stored)

    def _stored(self, task_id: str) -> tuple[str, str] | None:
        """(task name, status) of an ended task in the history; None when it holds none."""
        try:
            rows = self._history.query(HistoryQuery(task_id=task_id, limit=1)) if task_id else []
        except sqlite3.Error as error:
            NodeLog.of(self._node).warning(f'cannot read the task history: {error}')
            rows = []
        return (rows[0].task_name, rows[0].status) if rows else None
