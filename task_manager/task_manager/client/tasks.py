"""Tasks this client starts: their goals, sent again while unanswered, and their handles, ended
with whichever comes first, the ExecuteTask result or the task's message on
/task_manager/results, and stamped from the task's events.

A request with options (priority, on conflict, timeouts) goes to /task_manager/start_task
(StartTask: ExecuteTask's goal with TaskOptions, the same result), whose client is made on
first use; one without goes to ExecuteTask, as it always did.

Each event of /task_manager/task_events goes to the handle of its task by id.
"""

import math
import threading
import time
import uuid
from collections.abc import Iterator
from typing import Any, TypeVar

from rclpy.task import Future
from task_manager_msgs.action import ExecuteTask, StartTask
from task_manager_msgs.msg import TaskDoneResult
from task_manager_msgs.msg import TaskEvent as TaskEventMessage

from task_manager.client.connection import (
    GOAL_RESEND_WITHIN_SEC,
    SERVICE_RETRY_SEC,
    Connection,
    EventFeed,
)
from task_manager.client.handle import FeedbackCallback, TaskHandle
from task_manager.client.listeners import Callback, Inbox, Listener, Listeners, drain
from task_manager.client.message_values import json_text
from task_manager.client.missions import Subtask, mission_task_data
from task_manager.client.records import TaskEvent, TaskEventKind, TaskResult
from task_manager.client.watching import ActiveTasks
from task_manager.core.admission.options import OnConflict, RequestOptions, parse_on_conflict
from task_manager.core.bounds import PRIORITY, check_wait_seconds
from task_manager.core.errors import TaskManagerUnavailable
from task_manager.core.names import (
    ACTIVE_TASKS_TOPIC,
    CANCEL_TASK,
    EXECUTE_TASK_ACTION,
    MISSION,
    MISSION_SOURCE,
    RESULTS_TOPIC,
    START_TASK_ACTION,
    TASK_EVENT_BATCHES_TOPIC,
)
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.messages.task_messages import task_options_msg
from task_manager.rclpy_tools import qos
from task_manager.rclpy_tools.action_services import ActionServicesClient
from task_manager.rclpy_tools.futures import result_of
from task_manager.rclpy_tools.log import NodeLog

# How long a result that arrived before its task's ENDED event waits for it (for the stamps).
# The event is published first, so it is normally there already; this bounds a lost one.
ENDED_EVENT_GRACE_SEC = 2.0

NO_OPTIONS = RequestOptions()

T = TypeVar('T')


def check_priority(priority: int) -> int:
    """`priority`, if an int32; else ValueError saying what is allowed."""
    if isinstance(priority, bool) or not isinstance(priority, int):
        raise ValueError(f'priority must be an integer, got {priority!r}')
    PRIORITY.check('priority', priority)
    return priority


def request_options(
    priority: int | None = None,
    on_conflict: OnConflict | str | None = None,
    timeout_sec: float | None = None,
    queue_timeout_sec: float | None = None,
    feedback_timeout_sec: float | None = None,
) -> RequestOptions:
    """A request's options (None: the declaration's); ValueError says what is wrong."""
    mode = None if on_conflict is None else parse_on_conflict(on_conflict)
    seconds = {
        'timeout_sec': timeout_sec,
        'queue_timeout_sec': queue_timeout_sec,
        'feedback_timeout_sec': feedback_timeout_sec,
    }
    for name, value in seconds.items():
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f'{name} must be a number of seconds, got {value!r}')
        if not (value > 0 and math.isfinite(value)):
            raise ValueError(f'{name} must be a finite number of seconds > 0, got {value!r}')
    return RequestOptions(
        priority=None if priority is None else check_priority(priority),
        on_conflict=mode,
        timeout_sec=timeout_sec,
        queue_timeout_sec=queue_timeout_sec,
        feedback_timeout_sec=feedback_timeout_sec,
    )


class Tasks:
    """Starts tasks and missions, and keeps the handle of each until it ends."""

    def __init__(self, connection: Connection, active: ActiveTasks) -> None:
        self._connection = connection
        self._lock = connection.lock
        self._node = connection.node
        self._active = active
        self.results = Listeners[TaskResult](connection.lock)
        """Who gets every result of /task_manager/results."""
        self.events = EventFeed(connection, self._on_event)
        # key: task id, value: the handle of a task this client started and is waiting for
        self._handles_by_id: dict[str, TaskHandle] = {}
        # ExecuteTask through the action's own services: rclpy's ActionClient would also read
        # every status message, which lists every goal the node keeps (see action_services)
        self._execute_task = ActionServicesClient(self._node, ExecuteTask, EXECUTE_TASK_ACTION)
        self._start_task: ActionServicesClient | None = None
        """StartTask (a request with options), made on first use."""
        connection.subscribe(TaskDoneResult, RESULTS_TOPIC, qos.RESULTS, self._on_result)

    def serving(self) -> bool:
        """Whether the Task Manager's ExecuteTask server has met this client now."""
        return self._execute_task.server_is_ready()

    def wait_until_available(self, timeout_sec: float | None, *, events: bool) -> None:
        """See TaskManagerClient.wait_until_available."""
        check_wait_seconds(timeout_sec)
        timeout_sec = self._connection.timeout_sec if timeout_sec is None else timeout_sec
        if events:  # first: DDS matches both ends of it while we wait for the rest
            self.events.subscribe()
        if not self._execute_task.wait_for_server(timeout_sec):
            raise TaskManagerUnavailable(
                f'no Task Manager answered at {EXECUTE_TASK_ACTION} within {timeout_sec} s'
            )
        topics = {ACTIVE_TASKS_TOPIC, RESULTS_TOPIC}
        if not self._connection.wait_matched(topics, timeout_sec):
            raise TaskManagerUnavailable(
                f'the Task Manager topics did not connect within {timeout_sec} s'
            )
        if events:
            self.events.follow(timeout_sec)

    # ---- starting tasks ---------------------------------------------------------------------

    def start_task(
        self,
        task_name: str,
        task_data: dict[str, Any] | str | None,
        task_id: str,
        source: str,
        options: RequestOptions = NO_OPTIONS,
    ) -> TaskHandle:
        """Start a task; returns once the Task Manager has it (accepted, running or ended)."""
        handle = TaskHandle(self, task_id or str(uuid.uuid4()), task_name, source)
        return self._start(handle, task_data, options)

    def start_mission(
        self,
        subtasks: list[Subtask],
        task_id: str,
        source: str,
        options: RequestOptions = NO_OPTIONS,
    ) -> tuple[TaskHandle, list[str]]:
        """Start system/mission; its handle has a handle per subtask."""
        subtask_ids = [s.task_id or str(uuid.uuid4()) for s in subtasks]
        data = mission_task_data(subtasks, subtask_ids)
        handle = TaskHandle(self, task_id or str(uuid.uuid4()), MISSION, source)
        handle.subtasks = [
            TaskHandle(self, subtask_id, s.task_name, MISSION_SOURCE)
            for s, subtask_id in zip(subtasks, subtask_ids, strict=True)
        ]
        return self._start(handle, data, options), subtask_ids

    def _start(
        self, handle: TaskHandle, task_data: dict[str, Any] | str | None, options: RequestOptions
    ) -> TaskHandle:
        """Send the goal of `handle` (and follow its events, and those of its subtasks)."""
        fields = {
            'task_id': handle.task_id,
            'task_name': handle.task_name,
            'source': handle.source,
            'task_data': json_text(task_data),
        }
        if options.is_empty:
            goal, server = ExecuteTask.Goal(**fields), self._execute_task
        else:
            goal = StartTask.Goal(**fields, options=task_options_msg(options))
            server = self._start_task_server()
        handle.tracking.server = server
        self.events.follow()
        with self._lock:
            for each in (handle, *handle.subtasks):
                self._handles_by_id[each.task_id] = each
        if not self._send_goal(handle, goal, server):
            with self._lock:
                for each in (handle, *handle.subtasks):
                    self._handles_by_id.pop(each.task_id, None)
            raise TaskManagerUnavailable(
                f'the Task Manager did not answer the goal of {handle.task_name} within '
                f'{self._connection.timeout_sec} s'
            )
        return handle

    def _start_task_server(self) -> ActionServicesClient:
        """The client of StartTask, made on first use and waited for (bounded)."""
        with self._lock:
            if self._start_task is None:
                self._start_task = ActionServicesClient(self._node, StartTask, START_TASK_ACTION)
            server = self._start_task
        timeout_sec = self._connection.timeout_sec
        if not server.wait_for_server(timeout_sec):
            raise TaskManagerUnavailable(
                f'no Task Manager answered at {START_TASK_ACTION} within {timeout_sec} s (a '
                'Task Manager older than request options has none: start without priority, '
                'on_conflict or timeouts)'
            )
        return server

    def _send_goal(self, handle: TaskHandle, goal: Any, server: ActionServicesClient) -> bool:
        """Send the goal until the Task Manager answers (bounded); whether it did.

        A request sent just as DDS matches the node's reader can be lost, so the same goal
        (same goal id) is sent again (goal_resend_offsets): the node's action server refuses a
        goal id it already has, so it never runs twice.
        """
        started = time.monotonic()
        deadline = started + self._connection.timeout_sec
        goal_id, first = server.send_goal(goal)
        requests = [first]

        def answered() -> bool:
            return handle.goal_id is not None or handle.done() or self._active.has(handle.task_id)

        first.add_done_callback(lambda f: self._on_goal_response(handle, goal_id, f, retried=False))
        with self._lock:
            for offset in goal_resend_offsets(self._connection.timeout_sec):
                if self._lock.wait_for(answered, max(started + offset - time.monotonic(), 0)):
                    break
                _, again = server.send_goal(goal, goal_id)
                again.add_done_callback(
                    lambda f: self._on_goal_response(handle, goal_id, f, retried=True)
                )
                requests.append(again)
            done = self._lock.wait_for(answered, max(deadline - time.monotonic(), 0))
        for request in requests:
            if not request.done():
                server.forget_request(request)
        return done

    def cancel(self, handle: TaskHandle, timeout_sec: float) -> bool:
        """Cancel a task this client started, as its client (the task ends CANCELED)."""
        if handle.goal_id is None:
            data = {'cancelled_tasks': [handle.task_id]}
            return self.start_task(CANCEL_TASK, data, '', 'python').result().ok
        server = handle.tracking.server or self._execute_task
        response = _wait(server.cancel(handle.goal_id), timeout_sec)
        return response is not None and len(response.goals_canceling) > 0

    # ---- feedback ---------------------------------------------------------------------------

    def feedback_of(
        self, handle: TaskHandle, timeout_sec: float | None
    ) -> Iterator[dict[str, Any]]:
        """See TaskHandle.feedback."""
        self.events.follow()
        inbox: Inbox[dict[str, Any]] = Inbox()
        listeners = handle.tracking.feedback_listeners
        with self._lock:  # the latest first: no update can come between
            listeners.append(inbox)
            if handle.latest_feedback is not None:
                inbox.put(handle.latest_feedback)
        try:
            yield from drain(inbox, timeout_sec, handle.result_future)
        finally:
            with self._lock:
                listeners.remove(inbox)

    def add_feedback_callback(self, handle: TaskHandle, callback: FeedbackCallback) -> None:
        """Have `callback` get the feedback updates of `handle` from now on."""
        listener: Listener[dict[str, Any]] = Callback(callback, NodeLog.of(self._node))
        self.events.follow()
        with self._lock:
            handle.tracking.feedback_listeners.append(listener)

    # ---- callbacks (executor thread) ---------------------------------------------------------

    def _on_goal_response(
        self, handle: TaskHandle, goal_id: bytes, future: Future[Any], retried: bool
    ) -> None:
        """The node accepts every new goal: a refusal of a goal sent again means it has it.

        Its answers come in order, so an accepted request is answered before the refusal of
        the same goal sent again.
        """
        with self._lock:
            if handle.goal_id is not None:  # an answer to another request of the same goal
                return
            refused = not result_of(future).accepted and not retried
            if not refused:
                handle.goal_id = goal_id
                self._lock.notify_all()
        if refused:
            with_options = handle.tracking.server is self._start_task
            action = START_TASK_ACTION if with_options else EXECUTE_TASK_ACTION
            self._complete(handle, _refused(handle, action), final=True)
            return
        server = handle.tracking.server or self._execute_task
        server.get_result(goal_id).add_done_callback(
            lambda f: self._complete(
                handle,
                TaskResult.from_message(result_of(f).result, handle.task_name, handle.source),
            )
        )

    def _on_result(self, message: TaskDoneResult) -> None:
        result = TaskResult.from_message(message)
        with self._lock:
            self.results.put(result)
            handle = self._handles_by_id.get(result.task_id)
        if handle is not None and result.error_code is not ErrorCode.DUPLICATE_TASK_ID:
            self._complete(handle, result)

    def _on_event(self, message: TaskEventMessage) -> None:
        event = TaskEvent.from_message(message)
        task = event.task
        with self._lock:
            self.events.listeners.put(event)
            handle = self._handles_by_id.get(task.task_id)
            if (
                handle is None
                or task.error_code is ErrorCode.DUPLICATE_TASK_ID
                or (event.kind is TaskEventKind.RECEIVED and handle.tracking.state is not None)
            ):  # not ours, or another request refused for using our task's id
                return
            tracking = handle.tracking
            tracking.state = task
            feedback_listeners = (
                list(tracking.feedback_listeners) if event.kind is TaskEventKind.FEEDBACK else []
            )
        if task.feedback is not None:
            for feedback_listener in feedback_listeners:  # unlocked: callbacks may use the client
                feedback_listener.put(task.feedback)
        if event.kind is TaskEventKind.ENDED:
            self._complete(handle, tracking.early_result or task.to_result(), final=True)

    def _complete(self, handle: TaskHandle, result: TaskResult, final: bool = False) -> None:
        """End `handle` with `result`, and with the stamps of its task's events.

        A result that comes before the task's ENDED event (not `final`) waits for that event
        while the events reach us, at most ENDED_EVENT_GRACE_SEC: so the handle's result
        carries its end stamp, and its last feedback comes before its end.
        """
        tracking = handle.tracking
        with self._lock:
            if handle.done():
                return
            state = tracking.state
            # the events reach us if one of this task's did, or the stream is connected (a
            # result can overtake the events of a short task: they queue behind others')
            events_reach_us = state is not None or self._connection.is_matched(
                TASK_EVENT_BATCHES_TOPIC
            )
            if (
                not final
                and events_reach_us
                and result.error_code is not ErrorCode.DUPLICATE_TASK_ID
            ):
                if tracking.early_result is None:
                    tracking.early_result = result
                    tracking.early_result_timer = self._node.create_timer(
                        ENDED_EVENT_GRACE_SEC, lambda: self._end_waiting_for_event(handle)
                    )
                return
            if state is not None:
                result = result.with_stamps_of(state)
            timer, tracking.early_result_timer = tracking.early_result_timer, None
            self._handles_by_id.pop(handle.task_id, None)
            if state is not None:  # subtasks the mission never reached will have no events
                for subtask in handle.subtasks:
                    if subtask.tracking.state is None:
                        self._handles_by_id.pop(subtask.task_id, None)
            handle.result_future.set_result(result)
            self._lock.notify_all()
        if timer is not None:
            self._node.destroy_timer(timer)

    def _end_waiting_for_event(self, handle: TaskHandle) -> None:
        """The ENDED event of `handle` did not come in time: end it with what it has."""
        early_result = handle.tracking.early_result
        if early_result is not None:
            self._complete(handle, early_result, final=True)


def goal_resend_offsets(timeout_sec: float) -> list[float]:
    """When, in seconds after its first sending, a goal not answered is sent again: after
    SERVICE_RETRY_SEC, then twice as long, ...; only before the caller's timeout (a goal sent as
    the caller gives up would start a task it was told did not start) and within
    GOAL_RESEND_WITHIN_SEC."""
    offsets: list[float] = []
    wait_sec = SERVICE_RETRY_SEC
    while (at := (offsets[-1] if offsets else 0.0) + wait_sec) < min(
        timeout_sec, GOAL_RESEND_WITHIN_SEC
    ):
        offsets.append(at)
        wait_sec *= 2
    return offsets


def _refused(handle: TaskHandle, action: str) -> TaskResult:
    return TaskResult(
        task_id=handle.task_id,
        task_name=handle.task_name,
        status=TaskStatus.ERROR,
        error_code=ErrorCode.TASK_START_FAILED,
        result={'error': f'{action} rejected the goal'},
        source=handle.source,
    )


def _wait(future: Future[T], timeout_sec: float) -> T | None:
    check_wait_seconds(timeout_sec)
    done = threading.Event()
    future.add_done_callback(lambda _: done.set())
    return future.result() if done.wait(timeout_sec) or future.done() else None
