"""Action and service servers whose outcome, timing and cancel behaviour a test controls.

Goals and calls wait until the test ends them (`succeed`, `abort`, `respond`), or end at
once when the server is given an `on_goal`/`on_call` hook that does so. Decisions made on
the test's thread reach the executor through a guard condition, so nothing polls or sleeps.
"""

import threading
import time
from collections import deque
from collections.abc import Callable
from enum import Enum
from typing import Any

from rclpy.action.server import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.task import Future

from task_manager.rclpy_tools.futures import result_of
from task_manager.testing.harness import WaitTimeoutError, destroy_on_executor


class CancelPolicy(Enum):
    """What a scripted action server does with a cancel request."""

    END = 'end'
    """Accept it and end the goal CANCELED at once."""
    IGNORE = 'ignore'
    """Accept it but keep running until the test ends the goal."""
    REJECT = 'reject'
    """Reject the cancel request."""


class _ExecutorHop:
    """Runs functions on the executor thread, handed over from any thread."""

    def __init__(self, node: Node) -> None:
        self._pending: deque[Callable[[], None]] = deque()
        self._guard = node.create_guard_condition(self._drain)

    def call(self, function: Callable[[], None]) -> None:
        self._pending.append(function)
        self._guard.trigger()

    def _drain(self) -> None:
        while self._pending:
            self._pending.popleft()()


class _Arrivals:
    """A list that tests wait on as items arrive."""

    def __init__(self) -> None:
        self.items: list[Any] = []
        self._changed = threading.Condition()

    def add(self, item: Any) -> None:
        with self._changed:
            self.items.append(item)
            self._changed.notify_all()

    def wait_for(self, count: int, timeout_sec: float, what: str) -> list[Any]:
        with self._changed:
            if not self._changed.wait_for(lambda: len(self.items) >= count, timeout_sec):
                raise WaitTimeoutError(
                    f'{what}: {len(self.items)} of {count} arrived within {timeout_sec} s'
                )
            return list(self.items[:count])


class ScriptedGoal:
    """One goal received by a ScriptedActionServer."""

    def __init__(self, goal_handle: Any, hop: _ExecutorHop) -> None:
        self.goal_handle = goal_handle
        self.request = goal_handle.request
        self.cancel_requested = threading.Event()
        self.ended = threading.Event()
        # completes with (outcome, result): what the test decided
        self._end: Future[tuple[str, Any]] = Future()
        self._hop = hop

    def _decide(self, outcome: str, result: Any) -> None:
        if not self._end.done():
            self._end.set_result((outcome, result))

    def succeed(self, result: Any = None) -> None:
        self._hop.call(lambda: self._decide('succeed', result))

    def abort(self, result: Any = None) -> None:
        self._hop.call(lambda: self._decide('abort', result))

    def publish_feedback(self, feedback: Any) -> None:
        self._hop.call(lambda: self.goal_handle.publish_feedback(feedback))


def publish_feedback_until(
    goal: ScriptedGoal,
    feedback: Any,
    seen: Callable[[float], bool],
    timeout_sec: float,
    repeat_sec: float = 0.2,
) -> None:
    """Publish `feedback` again every `repeat_sec` until `seen(wait_sec)` is True.

    Feedback is volatile, as in ROS: one published before DDS matched its reader is lost.
    `seen` waits up to `wait_sec` for the feedback to show where the test looks.
    """
    deadline = time.monotonic() + timeout_sec
    while time.monotonic() < deadline:
        goal.publish_feedback(feedback)
        if seen(repeat_sec):
            return
    raise WaitTimeoutError(f'feedback {feedback} not seen within {timeout_sec} s')


class HeldGoalRequest:
    """A goal request whose answer (accept or reject) the server holds until the test decides."""

    def __init__(self, request: Any, hop: _ExecutorHop) -> None:
        self.request = request
        self._answer: Future[GoalResponse] = Future()
        self._hop = hop

    def accept(self) -> None:
        self._hop.call(lambda: self._decide(GoalResponse.ACCEPT))

    def reject(self) -> None:
        self._hop.call(lambda: self._decide(GoalResponse.REJECT))

    def _decide(self, answer: GoalResponse) -> None:
        if not self._answer.done():
            self._answer.set_result(answer)


class ScriptedActionServer:
    """An action server whose goals end when the test says so.

    With `hold_goal_requests`, each goal request waits in `held` until the test accepts or
    rejects it (the moment a client's goal is sent but not yet accepted by the server).
    `result_timeout`: how long (s) the server keeps a goal's result once it ended (rclpy's
    default 10; 0: it answers only the result requests waiting as the goal ends).
    """

    def __init__(
        self,
        node: Node,
        action_type: Any,
        topic: str,
        *,
        accept_goals: bool = True,
        cancel_policy: CancelPolicy = CancelPolicy.END,
        on_goal: Callable[[ScriptedGoal], None] | None = None,
        hold_goal_requests: bool = False,
        result_timeout: int = 10,
    ) -> None:
        self.action_type = action_type
        self.accept_goals = accept_goals
        self.hold_goal_requests = hold_goal_requests
        self.held = _Arrivals()
        self.cancel_policy = cancel_policy
        self.goals = _Arrivals()
        self.rejected = _Arrivals()
        self._on_goal = on_goal
        self._node = node
        self._hop = _ExecutorHop(node)
        self._goals_by_id: dict[bytes, ScriptedGoal] = {}
        # ids of goals cancelled between their acceptance and their execute callback
        self._cancelled_before_execution: set[bytes] = set()
        self.server = ActionServer(
            node,
            action_type,
            topic,
            execute_callback=self._execute,
            # rclpy awaits a coroutine goal callback; its types name plain callables only
            goal_callback=self._hold_goal if hold_goal_requests else self._goal,  # type: ignore[arg-type]
            cancel_callback=self._cancel,
            callback_group=ReentrantCallbackGroup(),
            result_timeout=result_timeout,
        )

    async def _hold_goal(self, request: Any) -> GoalResponse:
        held = HeldGoalRequest(request, self._hop)
        self.held.add(held)
        await held._answer
        return result_of(held._answer)

    def _goal(self, request: Any) -> GoalResponse:
        if self.accept_goals:
            return GoalResponse.ACCEPT
        self.rejected.add(request)
        return GoalResponse.REJECT

    def _cancel(self, goal_handle: Any) -> CancelResponse:
        key = bytes(goal_handle.goal_id.uuid)
        goal = self._goals_by_id.get(key)
        if goal is None:  # accepted, but its execute callback has not run yet: applied there
            self._cancelled_before_execution.add(key)
            return self._cancel_answer()
        self._apply_cancel(goal)
        return self._cancel_answer()

    def _cancel_answer(self) -> CancelResponse:
        if self.cancel_policy is CancelPolicy.REJECT:
            return CancelResponse.REJECT
        return CancelResponse.ACCEPT

    def _apply_cancel(self, goal: ScriptedGoal) -> None:
        goal.cancel_requested.set()
        if self.cancel_policy is CancelPolicy.END:
            goal._decide('canceled', None)

    async def _execute(self, goal_handle: Any) -> Any:
        goal = ScriptedGoal(goal_handle, self._hop)
        key = bytes(goal_handle.goal_id.uuid)
        self._goals_by_id[key] = goal
        if key in self._cancelled_before_execution:
            self._cancelled_before_execution.discard(key)
            self._apply_cancel(goal)
        self.goals.add(goal)
        if self._on_goal is not None:
            self._on_goal(goal)
        await goal._end
        outcome, result = result_of(goal._end)
        if outcome == 'canceled' and goal_handle.is_cancel_requested:
            goal_handle.canceled()
        elif outcome == 'succeed':
            goal_handle.succeed()
        else:
            goal_handle.abort()
        goal.ended.set()
        return result if result is not None else self.action_type.Result()

    def wait_for_goals(self, count: int, timeout_sec: float) -> list[ScriptedGoal]:
        return self.goals.wait_for(count, timeout_sec, 'goals')

    def wait_for_held(self, count: int, timeout_sec: float) -> list[HeldGoalRequest]:
        return self.held.wait_for(count, timeout_sec, 'held goal requests')

    def destroy(self) -> None:
        destroy_on_executor(self._node, self.server)


class ScriptedCall:
    """One request received by a ScriptedService."""

    def __init__(self, request: Any, response_type: Any, hop: _ExecutorHop) -> None:
        self.request = request
        self._response_type = response_type
        self._response: Future[Any] = Future()
        self._hop = hop

    def respond(self, **fields: Any) -> None:
        """Send the response, with `fields` set on it."""
        self._hop.call(lambda: self._set(fields))

    def _set(self, fields: dict[str, Any]) -> None:
        if not self._response.done():
            self._response.set_result(self._response_type(**fields))


class ScriptedService:
    """A service whose calls return when the test says so (services cannot be cancelled)."""

    def __init__(
        self,
        node: Node,
        service_type: Any,
        topic: str,
        *,
        on_call: Callable[[ScriptedCall], None] | None = None,
    ) -> None:
        self.calls = _Arrivals()
        self._service_type = service_type
        self._on_call = on_call
        self._hop = _ExecutorHop(node)
        self._node = node
        self.service = node.create_service(
            service_type, topic, self._handle, callback_group=ReentrantCallbackGroup()
        )

    async def _handle(self, request: Any, _response: Any) -> Any:
        call = ScriptedCall(request, self._service_type.Response, self._hop)
        self.calls.add(call)
        if self._on_call is not None:
            self._on_call(call)
        return await call._response

    def wait_for_calls(self, count: int, timeout_sec: float) -> list[ScriptedCall]:
        return self.calls.wait_for(count, timeout_sec, 'calls')

    def destroy(self) -> None:
        self._node.destroy_service(self.service)
