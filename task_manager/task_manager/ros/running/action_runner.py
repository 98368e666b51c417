"""Running tasks on existing ROS 2 action servers."""

import uuid
from collections import deque
from collections.abc import Callable
from typing import Any

from action_msgs.msg import GoalStatus
from action_msgs.srv import CancelGoal
from rclpy.node import Node
from rclpy.task import Future

from task_manager.core.errors import TaskRequestError
from task_manager.core.status import ErrorCode, ServerOutcome, TaskStatus
from task_manager.core.task import TaskEnd, TaskRecord, status_for_action_outcome
from task_manager.core.task_spec import TaskSpec
from task_manager.messages.json_codec import message_from_json, message_to_dict
from task_manager.rclpy_tools.action_services import ActionServicesClient
from task_manager.rclpy_tools.futures import (
    first_completed,
    resolved,
    wait_for,
    wait_until_ready,
)
from task_manager.ros.running.execution import RunnerTimeouts, TaskRunner
from task_manager.ros.running.server_watch import ServerWatch, WatchSettings

# key: terminal GoalStatus value, value: how the server ended the goal
_OUTCOMES = {
    GoalStatus.STATUS_SUCCEEDED: ServerOutcome.SUCCEEDED,
    GoalStatus.STATUS_CANCELED: ServerOutcome.CANCELED,
    GoalStatus.STATUS_ABORTED: ServerOutcome.ABORTED,
}


def server_outcome(goal_status: int) -> ServerOutcome:
    """The one place GoalStatus becomes a ServerOutcome; anything unexpected is ABORTED."""
    return _OUTCOMES.get(goal_status, ServerOutcome.ABORTED)


# How long a cancel request may go unanswered before it is sent again.
CANCEL_AGAIN_SEC = 1.0
# How many times a goal's result is asked for again while none comes: after 1, 2, 4, ... 64
# ticks of the server watch (about two minutes at the default server_check_period), then no
# more unless its server restarts.
RESULT_ASKS_AGAIN_MAX = 7
# How many of a goal's latest requests asked again stay awaited (with its first request).
RESULT_ASKS_KEPT = 3


class ActionExecution:
    """A goal accepted by a task's action server.

    Its result was asked for right behind the goal (the runner's `start`; asked again if the
    server answered that request before it had the goal), and that request stays awaited until
    the task ends: a server holds it while the goal runs and answers it as the goal ends, even
    one that keeps no result afterwards (rclpy's result_timeout, 10 s by default; 0 on some
    servers). It is asked again while no answer comes, since a busy server's result service
    keeps only its last few unread requests (10 by default, rclpy's and rclcpp's) and drops
    older ones unanswered: the watch's tick asks again once the last request has waited 1, then
    2, 4, up to 64 ticks, RESULT_ASKS_AGAIN_MAX times in all; one still waiting its turn in the
    request window keeps its place (none is added behind it). Then no more: the server holds
    every request it took and answers each as the goal ends, so asking on for hours would pile
    up answers that, for a thousand goals ending at once, overflow the node's reader and lose
    the only ones that count (their goal's result then expired on the server before the next
    ask). A server that restarted is noticed by its new DDS ids (`server_ids`, checked at each
    tick): the result is asked for again at once. The latest RESULT_ASKS_KEPT requests asked
    again stay awaited too: forgetting one costs a scan of the client's pending requests
    (rclpy's). A server that no longer knows the goal (STATUS_UNKNOWN: it restarted, or let the
    result expire) ends the task ERROR.
    """

    def __init__(
        self,
        node: Node,
        client: ActionServicesClient,
        goal_id: bytes,
        spec: TaskSpec,
        server_ids: Callable[[], frozenset[bytes]],
        server_alive: Callable[[], None],
        servers_known: bool,
        sent_with_goal: Future[Any] | None = None,
    ) -> None:
        """`server_ids`: the DDS ids of the action's servers as of the watch's last tick;
        `servers_known`: whether that tick is recent (the watch was ticking), else the goal's
        servers are those of its first tick (which asks for the result again anyway: a
        server restarted before it loses nothing); `server_alive` is told each answer of the
        server; `sent_with_goal`: the GetResult request sent right behind the goal, before
        the server accepted it (see `_on_result_sent_with_goal`), else the result is asked
        for now."""
        self._node = node
        self._server_alive = server_alive
        self._client = client
        self._goal_id = goal_id
        self._spec = spec
        self._server_ids = server_ids
        self._servers_of_goal: frozenset[bytes] | None = server_ids() if servers_known else None
        self.outcome: Future[Any] = Future()
        self._ask_at: int | None = None  # the watch's check at which to ask again (first: next)
        self._ticks_between_asks = 1
        self._asks_again = 0
        # the latest requests asked again, oldest first
        self._asked_again: deque[Future[Any]] = deque()
        self.outcome.add_done_callback(lambda _: self._forget())
        if sent_with_goal is None:
            self._first_request = self._ask_for_result()
        else:
            self._first_request = sent_with_goal
            sent_with_goal.add_done_callback(self._on_result_sent_with_goal)

    def _ask_for_result(self, again: bool = False) -> Future[Any]:
        request = self._client.get_result(self._goal_id, again)
        request.add_done_callback(self._on_result)
        return request

    def on_watch_tick(self, tick: int) -> int | None:
        """Ask for the result again if the last request has waited its interval unanswered
        (RESULT_ASKS_AGAIN_MAX times), or at once if the server restarted; the check at which
        to ask next."""
        if self.outcome.done():
            return None
        if self._server_restarted():
            self._ask_again()
        elif self._asks_again < RESULT_ASKS_AGAIN_MAX and (
            self._ask_at is None or tick >= self._ask_at
        ):
            self._ticks_between_asks *= 2
            self._ask_at = tick + self._ticks_between_asks
            if not (self._asked_again and self._client.result_request_waits(self._asked_again[-1])):
                self._asks_again += 1
                self._ask_again()
        return self._ask_at if self._asks_again < RESULT_ASKS_AGAIN_MAX else None

    def _server_restarted(self) -> bool:
        """Whether none of the servers known when the goal was accepted is there any more,
        and others are (a server gone without another is the watch's to notice)."""
        now = self._server_ids()
        if self._servers_of_goal is None:
            self._servers_of_goal = now
            return False
        if not now or now == self._servers_of_goal:
            return False
        restarted = bool(self._servers_of_goal) and not (now & self._servers_of_goal)
        self._servers_of_goal = now
        return restarted

    def _ask_again(self) -> None:
        if len(self._asked_again) == RESULT_ASKS_KEPT:
            self._client.forget_result_request(self._asked_again.popleft())
        self._asked_again.append(self._ask_for_result(again=True))

    def _forget(self) -> None:
        self._client.forget(self._goal_id)
        for request in (self._first_request, *self._asked_again):
            if not request.done():
                self._client.forget_result_request(request)

    def _on_result_sent_with_goal(self, future: Future[Any]) -> None:
        """The answer to the request sent right behind the goal: the goal's result (the server
        held the request until the goal ended, a hop saved on every task), or STATUS_UNKNOWN
        when the server took that request before the goal (the two travel on topics of their
        own, in no set order): then it is asked for now, the server having accepted the goal,
        and only that answer's STATUS_UNKNOWN ends the task."""
        response = future.result()
        if response is None or response.status != GoalStatus.STATUS_UNKNOWN:
            self._on_result(future)
            return
        self._server_alive()
        if not self.outcome.done():
            self._first_request = self._ask_for_result()

    def _on_result(self, future: Future[Any]) -> None:
        response = future.result()
        if response is None:  # forgotten
            return
        self._server_alive()
        if self.outcome.done():
            return
        if response.status == GoalStatus.STATUS_UNKNOWN:
            self.fail(
                f'action server {self._spec.topic} no longer knows the goal '
                '(it restarted, or its result expired before it was asked for)'
            )
            return
        status = status_for_action_outcome(server_outcome(response.status), self._spec)
        self.outcome.set_result(TaskEnd(status, message_to_dict(response.result)))

    def fail(self, reason: str) -> None:
        """End the task ERROR without its server (e.g. the server is gone)."""
        if not self.outcome.done():
            self.outcome.set_result(TaskEnd(TaskStatus.ERROR, {'error': reason}))

    async def cancel(self, timeout_sec: float) -> bool:
        """Ask the server to cancel the goal, again each CANCEL_AGAIN_SEC while it has not
        answered (a busy server drops requests beyond its last 10 unread: a cancel is safe to
        repeat); True once the goal has ended within `timeout_sec`."""
        if self.outcome.done():
            return True
        clock = self._node.get_clock()
        started = clock.now()

        def remaining_sec() -> float:
            return timeout_sec - (clock.now() - started).nanoseconds / 1e9

        while True:
            cancel_future = self._client.cancel(self._goal_id)
            answered_or_ended = first_completed([cancel_future, self.outcome])
            wait_sec = min(CANCEL_AGAIN_SEC, remaining_sec())
            if await wait_for(self._node, answered_or_ended, wait_sec):
                break
            self._client.forget_cancel_request(cancel_future)
            if remaining_sec() <= 0:
                return self.outcome.done()
        if self.outcome.done():
            return True
        response = cancel_future.result()
        if response is None or response.return_code == CancelGoal.Response.ERROR_REJECTED:
            return self.outcome.done()
        return await wait_for(self._node, self.outcome, remaining_sec())


class ActionTaskRunner(TaskRunner):
    """Starts goals of one declared action task and watches its server while they run."""

    def __init__(
        self, node: Node, spec: TaskSpec, action_type: Any, timeouts: RunnerTimeouts
    ) -> None:
        self.spec = spec
        self._node = node
        self._action_type = action_type
        self._timeouts = timeouts
        # a server silent for goal_response_timeout has lost the requests it holds unanswered
        self._client = ActionServicesClient(
            node,
            action_type,
            spec.topic,
            timeouts.server_requests_in_flight,
            timeouts.goal_response_sec,
        )
        self._server_ids: frozenset[bytes] = frozenset()
        self._last_probe: Future[Any] | None = None
        self._watch = ServerWatch(
            node,
            self._probe,
            WatchSettings(timeouts.server_check_period_sec, timeouts.server_loss_timeout_sec),
            loss=f'action server {spec.topic} stopped answering for more than '
            f'{timeouts.server_loss_timeout_sec} s',
            on_tick=self._note_server_ids,
        )

    def parse(self, task_data: str, task_id: str) -> Any:
        return message_from_json(self._action_type.Goal, task_data)

    async def start(self, message: Any, record: TaskRecord) -> ActionExecution:
        topic = self.spec.topic
        if not await wait_until_ready(
            self._node, self._client.server_is_ready, self._timeouts.server_wait_sec
        ):
            raise TaskRequestError(
                ErrorCode.TASK_START_FAILED, f'action server {topic} is not available'
            )

        def on_feedback(feedback: Any) -> None:
            self._watch.mark_alive()
            if record.status is TaskStatus.IN_PROGRESS:
                record.record_feedback(message_to_dict(feedback))

        goal_id, goal_future = self._client.send_goal(message, feedback_callback=on_feedback)
        # goal_response_timeout is the server's time: from when the goal left the request
        # window (a burst waits there its turn, 8 at a time), not from when it was queued
        await resolved(self._node, self._client.goal_sent(goal_future))
        # the result asked for right behind the goal, not once it is accepted: the server
        # holds the request until the goal ends (ActionExecution._on_result_sent_with_goal)
        result_request = self._client.get_result(goal_id)
        if not await wait_for(self._node, goal_future, self._timeouts.goal_response_sec):
            self._client.forget_result_request(result_request)
            goal_future.add_done_callback(lambda f: self._cancel_late_goal(goal_id, f))
            raise TaskRequestError(
                ErrorCode.TASK_START_FAILED,
                f'action server {topic} did not answer the goal within '
                f'{self._timeouts.goal_response_sec} s',
            )
        response = goal_future.result()
        if response is not None:
            self._watch.mark_alive()
        if response is None or not response.accepted:
            self._client.forget(goal_id)
            self._client.forget_result_request(result_request)
            raise TaskRequestError(
                ErrorCode.TASK_START_FAILED, f'action server {topic} rejected the goal'
            )
        try:
            # the ids of the last tick are of long ago when the watch is idle: reading them
            # now is a query of the DDS graph for each task (4.5 % of the node's time for
            # tasks one by one), so the goal's first tick reads them
            execution = ActionExecution(
                self._node,
                self._client,
                goal_id,
                self.spec,
                lambda: self._server_ids,
                self._watch.mark_alive,
                servers_known=self._watch.watching,
                sent_with_goal=result_request,
            )
            self._watch.track(execution)
        except Exception as error:  # a bug of ours must not leave the goal running untracked
            self._client.forget_result_request(result_request)
            raise TaskRequestError(
                ErrorCode.TASK_START_FAILED,
                f'the Task Manager failed to track the goal {topic} accepted ({error!r}); '
                + await self._withdraw(goal_id),
            ) from error
        return execution

    async def _withdraw(self, goal_id: bytes) -> str:
        """Cancel an accepted goal that cannot be tracked and wait (within cancel_timeout) for
        its end; what became of it, for the task's result."""
        timeout_sec = self.spec.cancel_timeout_sec
        self._client.forget(goal_id)
        self._client.cancel(goal_id)
        if await wait_for(self._node, self._client.get_result(goal_id), timeout_sec):
            return 'it was cancelled on its server'
        return (
            f'its cancel was not confirmed within cancel_timeout {timeout_sec:g} s: '
            'the goal may still run'
        )

    def _note_server_ids(self) -> bool:
        """Read the servers' DDS ids at a check of the watch; whether they changed (then each
        goal is told, to notice a restart of its server)."""
        before, self._server_ids = self._server_ids, self._client.server_ids()
        return self._server_ids != before

    def _probe(self) -> bool | Future[Any]:
        """A cancel request for a goal id that does not exist: a live server answers at
        once, and it cancels nothing. The probe before it, if still unanswered, is forgotten:
        one goes out each check, and a server that answers none must not leave a request
        waiting for each."""
        if self._last_probe is not None and not self._last_probe.done():
            self._client.forget_cancel_request(self._last_probe)
        self._last_probe = None
        if not self._client.server_is_ready():
            return False
        self._last_probe = self._client.cancel(uuid.uuid4().bytes)
        return self._last_probe

    def _cancel_late_goal(self, goal_id: bytes, goal_future: Future[Any]) -> None:
        """A goal accepted after its start timed out would run untracked: cancel it."""
        self._client.forget(goal_id)
        response = goal_future.result()
        if response is not None and response.accepted:
            self._client.cancel(goal_id)
