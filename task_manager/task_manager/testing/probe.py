"""A test client of a running Task Manager that uses only its public ROS interfaces."""

import json
import uuid
from collections.abc import Callable
from typing import Any

from action_msgs.msg import GoalStatus
from rclpy.action.client import ClientGoalHandle
from task_manager_msgs.action import ExecuteTask, StartTask
from task_manager_msgs.msg import ActiveTaskArray, TaskDoneResult, TaskEvent, TaskOptions
from unique_identifier_msgs.msg import UUID

from task_manager.core.names import (
    ACTIVE_TASKS_TOPIC,
    EXECUTE_TASK_ACTION,
    RESULTS_TOPIC,
    START_TASK_ACTION,
    TASK_EVENTS_TOPIC,
)
from task_manager.rclpy_tools import qos
from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.testing.harness import (
    RosHarness,
    TopicRecorder,
    WaitTimeoutError,
    wait_for_future,
)

SendGoalResponse = ExecuteTask.Impl.SendGoalService.Response
DEFAULT_TIMEOUT_SEC = 15.0
WARM_UP_ATTEMPTS = 5
WARM_UP_TIMEOUT_SEC = 2.0
# an undeclared name: refused at once, with RECEIVED and ENDED events
EVENTS_WARM_UP_TASK = 'events/warm-up'


def execute_task_client(
    ros: RosHarness, action_type: Any = ExecuteTask, name: str = EXECUTE_TASK_ACTION
) -> Any:
    """An ExecuteTask (or StartTask) action client with deep queues: bursts are not dropped."""
    return ros.action_client(
        action_type,
        name,
        goal_service_qos_profile=qos.DEEP_RELIABLE,
        result_service_qos_profile=qos.DEEP_RELIABLE,
        cancel_service_qos_profile=qos.DEEP_RELIABLE,
    )


def warm_up(client: Any) -> None:
    """Ask for the result of a goal the server never had until one such round trip succeeds.

    Seeing the server is not enough: DDS may match the server's reply path to a new client a
    moment later, and a reply sent before that is lost. This request is answered at once
    (status UNKNOWN) and creates no task, so nothing lands in any history. The server learns
    of the client's goal, cancel and result services in the order rcl_action creates them,
    so once a result reply arrives, goal replies do too.
    """
    for _ in range(WARM_UP_ATTEMPTS):
        goal_id = UUID(uuid=list(uuid.uuid4().bytes))
        unknown = ClientGoalHandle(client, goal_id, SendGoalResponse(accepted=True))
        try:
            response = wait_for_future(
                unknown.get_result_async(), WARM_UP_TIMEOUT_SEC, 'warm-up result'
            )
        except WaitTimeoutError:
            continue
        assert response.status == GoalStatus.STATUS_UNKNOWN, response
        return
    raise WaitTimeoutError(f'no ExecuteTask round trip in {WARM_UP_ATTEMPTS} tries')


def _has_ended(task_id: str) -> Callable[[list[TaskEvent]], bool]:
    return lambda events: any(
        e.task.task_id == task_id and e.event == TaskEvent.ENDED for e in events
    )


class TaskManagerProbe:
    """Sends ExecuteTask goals and records /task_manager/active_tasks and /results."""

    def __init__(self, ros: RosHarness, timeout_sec: float = DEFAULT_TIMEOUT_SEC) -> None:
        self.ros = ros
        self.timeout_sec = timeout_sec
        self.client = execute_task_client(ros)
        self._start_client: Any = None
        self.results: TopicRecorder = ros.record(TaskDoneResult, RESULTS_TOPIC, qos.RESULTS)
        self.active: TopicRecorder = ros.record(
            ActiveTaskArray, ACTIVE_TASKS_TOPIC, qos.ACTIVE_TASKS
        )

    def wait_until_connected(self) -> None:
        """Wait until goals, results and both topics work end to end (see warm_up)."""
        ready = wait_until_ready(self.client.server_is_ready, self.timeout_sec)
        assert ready, 'no execute_task server'
        self.results.wait_matched(self.timeout_sec)
        self.active.wait_matched(self.timeout_sec)
        warm_up(self.client)

    def record_events(self) -> TopicRecorder:
        """Record /task_manager/task_events from the moment the node's events reach us.

        The subscription seeing the node's publisher is not enough: the publisher may match
        it a moment later, and an event sent before that (volatile) never comes. So refused
        tasks (an unknown name: RECEIVED and ENDED, nothing started) are sent until the ENDED
        of one arrives; tests pick their own tasks' events by id.
        """
        events = self.ros.record(TaskEvent, TASK_EVENTS_TOPIC, qos.TASK_EVENTS)
        events.wait_matched(self.timeout_sec)
        for attempt in range(WARM_UP_ATTEMPTS):
            task_id = f'events-warm-up-{attempt}'
            self.run(EVENTS_WARM_UP_TASK, {}, task_id=task_id)
            try:
                events.wait_until(_has_ended(task_id), WARM_UP_TIMEOUT_SEC, 'warm-up event')
            except WaitTimeoutError:
                continue
            return events
        raise WaitTimeoutError(f'no task event in {WARM_UP_ATTEMPTS} tries')

    def send(
        self, task_name: str, task_data: Any = None, task_id: str = '', source: str = 'test'
    ) -> Any:
        """Send a goal (task_data as a dict, or a raw string); return the accepted goal handle."""
        data = task_data if isinstance(task_data, str) else json.dumps(task_data or {})
        goal = ExecuteTask.Goal(task_id=task_id, task_name=task_name, source=source, task_data=data)
        handle = wait_for_future(self.ros.send_goal(self.client, goal), self.timeout_sec, 'goal')
        assert handle.accepted
        return handle

    def start(
        self,
        task_name: str,
        task_data: Any = None,
        task_id: str = '',
        source: str = 'test',
        **options: Any,
    ) -> Any:
        """Send a StartTask goal with TaskOptions fields (priority=5 sets has_priority)."""
        if self._start_client is None:
            self._start_client = execute_task_client(self.ros, StartTask, START_TASK_ACTION)
            assert wait_until_ready(self._start_client.server_is_ready, self.timeout_sec)
            warm_up(self._start_client)
        if 'priority' in options:
            options['has_priority'] = True
        data = task_data if isinstance(task_data, str) else json.dumps(task_data or {})
        goal = StartTask.Goal(
            task_id=task_id,
            task_name=task_name,
            source=source,
            task_data=data,
            options=TaskOptions(**options),
        )
        handle = wait_for_future(
            self.ros.send_goal(self._start_client, goal), self.timeout_sec, 'goal'
        )
        assert handle.accepted
        return handle

    def run_started(self, task_name: str, task_data: Any = None, **kwargs: Any) -> Any:
        """StartTask to its end: the result (see start for the options)."""
        return self.result_of(self.start(task_name, task_data, **kwargs)).result

    def result_of(self, goal_handle: Any) -> Any:
        """Wait for a goal's result; returns the wrapped response (.status and .result)."""
        return wait_for_future(goal_handle.get_result_async(), self.timeout_sec, 'result')

    def run(self, task_name: str, task_data: Any = None, **kwargs: Any) -> ExecuteTask.Result:
        return self.result_of(self.send(task_name, task_data, **kwargs)).result

    def cancel(self, goal_handle: Any) -> Any:
        return wait_for_future(goal_handle.cancel_goal_async(), self.timeout_sec, 'cancel')

    def wait_result_message(self, task_id: str) -> TaskDoneResult:
        """Wait for the /task_manager/results message of `task_id`."""
        return self.results.wait_until(
            lambda msgs: next((m for m in msgs if m.task_id == task_id), None),
            self.timeout_sec,
            f'result of {task_id}',
        )

    def results_for(self, task_id: str) -> list[TaskDoneResult]:
        return [m for m in self.results.snapshot() if m.task_id == task_id]

    def wait_active(self, predicate: Any, what: str = 'active tasks') -> ActiveTaskArray:
        """Wait for an active_tasks message satisfying `predicate(list of (id, status))`."""
        return self.active.wait_until(
            lambda msgs: next(
                (
                    m
                    for m in reversed(msgs)
                    if predicate([(t.task_id, t.task_status) for t in m.active_tasks])
                ),
                None,
            ),
            self.timeout_sec,
            what,
        )

    def wait_in_progress(self, task_id: str) -> None:
        self.wait_active(lambda tasks: (task_id, 'IN_PROGRESS') in tasks, f'{task_id} active')

    def destroy(self) -> None:
        """Destroy its clients and subscriptions on the thread spinning them (see
        RosHarness.destroy)."""
        self.ros.destroy(self.client)
        if self._start_client is not None:
            self.ros.destroy(self._start_client)
        for recorder in (self.results, self.active):
            self.ros.destroy(recorder)
