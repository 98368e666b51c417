"""A goal the Task Manager does not answer is sent again only while its client waits: none goes
out as the client gives up (it would start a task its caller was told did not start)."""

import math
import threading
import time
from typing import Any

import pytest
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.task import Future
from task_manager_msgs.action import ExecuteTask

from task_manager.client import TaskManagerClient
from task_manager.client.tasks import goal_resend_offsets
from task_manager.core.errors import TaskManagerUnavailable
from task_manager.testing.harness import RosHarness

TIMEOUT_SEC = 2.0
# a goal sent as the client gave up reaches the server well within this
LATE_GOAL_BOUND_SEC = 1.0


class SilentGoalService:
    """ExecuteTask's send_goal service that takes every goal and answers none."""

    def __init__(self, ros: RosHarness) -> None:
        self.received: list[float] = []
        self.changed = threading.Condition()
        self._never: Future[None] = Future()
        self.service = ros.on_executor(
            lambda: ros.node.create_service(
                ExecuteTask.Impl.SendGoalService,
                '/task_manager/execute_task/_action/send_goal',
                self._take,
                callback_group=ReentrantCallbackGroup(),  # each goal held at once
            )
        )
        self._ros = ros

    def release(self) -> None:
        """Let the goals held go (answered once no client waits), so the test node ends."""
        self._ros.on_executor(lambda: self._never.set_result(None))

    async def _take(self, request: Any, response: Any) -> Any:
        with self.changed:
            self.received.append(time.monotonic())
            self.changed.notify_all()
        await self._never
        return response


def test_a_goal_unanswered_is_not_sent_again_as_the_client_gives_up(ros: RosHarness) -> None:
    silent = SilentGoalService(ros)
    last_resend = goal_resend_offsets(TIMEOUT_SEC)[-1]
    with TaskManagerClient('goal_resend', timeout_sec=TIMEOUT_SEC) as client:
        started = time.monotonic()
        with pytest.raises(TaskManagerUnavailable, match='did not answer the goal'):
            client.start_task('drive', {'order': 1}, task_id='unanswered')
        # a goal sent as the client gave up would arrive within the bound
        with silent.changed:
            silent.changed.wait_for(
                lambda: bool(silent.received) and silent.received[-1] > started + TIMEOUT_SEC,
                LATE_GOAL_BOUND_SEC,
            )
    silent.release()

    sent_after = [at - started for at in silent.received]
    assert sent_after, 'no goal reached the service'
    # the last one sent again, give or take its delivery, not one at the timeout
    assert max(sent_after) < (last_resend + TIMEOUT_SEC) / 2, sent_after


@pytest.mark.parametrize('timeout_sec', [math.inf, math.nan, -1.0, 8 * 24 * 3600.0])
def test_a_client_refuses_a_timeout_it_cannot_wait(timeout_sec: float) -> None:
    """Infinity reached threading's waits (OverflowError as the client closed); a week at most."""
    with pytest.raises(ValueError, match='timeout_sec must be'):
        TaskManagerClient('unbounded_timeout', timeout_sec=timeout_sec)


@pytest.mark.usefixtures('ros_context')
def test_a_clients_timeout_set_later_and_its_calls_waits_are_bounded_too() -> None:
    """No Task Manager runs here: a wait let through would never end."""
    with TaskManagerClient('bounded_timeout', timeout_sec=TIMEOUT_SEC) as client:
        with pytest.raises(ValueError, match='timeout_sec must be a finite number'):
            client.timeout_sec = math.inf
        assert client.timeout_sec == TIMEOUT_SEC
        for wait in (client.wait_until_available, client.active_tasks):
            with pytest.raises(ValueError, match='timeout_sec must be a finite number'):
                wait(math.inf)
        with pytest.raises(ValueError, match='timeout_sec must be a finite number'):
            next(client.results(math.inf))
        with pytest.raises(ValueError, match='timeout_sec must be a finite number'):
            client.why('a-task', timeout_sec=math.inf)  # a service call
