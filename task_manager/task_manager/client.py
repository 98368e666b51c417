"""`TaskManagerClient`: start, watch, cancel, pause and schedule tasks of a running Task Manager.

The client generates every task id itself and takes a task's outcome from whichever comes
first, the ExecuteTask result or the task's message on /task_manager/results, so a lost
reply on the network never leaves a script waiting: every wait is bounded.

Stamps and feedback come from /task_manager/task_events, which a client subscribes to once,
on first use (starting a task, asking for feedback or events); each event goes to the
handle of its task by id. A client that joins late asks /task_manager/get_task_states.
"""

import contextlib
import queue
import threading
import time
import traceback
import uuid
import weakref
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime, timedelta
from enum import Enum, StrEnum
from typing import Any, Generic, Protocol, TypeAlias, TypeVar

import rclpy
from builtin_interfaces.msg import Time
from rcl_interfaces.srv import GetParameters, ListParameters
from rclpy.client import Client
from rclpy.context import Context
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import parameter_value_to_python
from rclpy.qos import QoSProfile
from rclpy.task import Future
from rclpy.timer import Timer
from task_manager_msgs.action import ExecuteTask
from task_manager_msgs.msg import ActiveTaskArray, TaskDoneResult
from task_manager_msgs.msg import TaskEvent as TaskEventMessage
from task_manager_msgs.srv import GetTaskResults, GetTaskStates, QueryTaskHistory

from task_manager.core.errors import TaskManagerUnavailable, TaskTimeout
from task_manager.core.names import (
    ACTIVE_TASKS_TOPIC,
    CANCEL_TASK,
    EXECUTE_TASK_ACTION,
    GET_TASK_RESULTS_SERVICE,
    GET_TASK_STATES_SERVICE,
    HISTORY_QUERY_LIMIT_MAX,
    MISSION,
    MISSION_SOURCE,
    QUERY_TASK_HISTORY_SERVICE,
    RESULTS_TOPIC,
    STOP,
    TASK_EVENTS_TOPIC,
)
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.core.system_tasks import SYSTEM_SPECS
from task_manager.core.task_stats import TaskStats, task_stats
from task_manager.message_values import datetime_of, json_object, json_text, stamp_of
from task_manager.missions import Subtask as Subtask  # public here too, as before
from task_manager.missions import mission_task_data
from task_manager.pauses import Pause as Pause  # the type of TaskState.pauses
from task_manager.pauses import PauseMethods, parse_pauses, paused_time, running_time
from task_manager.rclpy_tools import qos
from task_manager.rclpy_tools.action_services import ActionServicesClient
from task_manager.rclpy_tools.cleanup import destroy_waitables
from task_manager.rclpy_tools.futures import result_of
from task_manager.schedules import ScheduleMethods

FINAL_STATUSES = tuple(s.value for s in TaskStatus if s.is_final)
TASK_MANAGER_NODE = '/task_manager'
LIST_PARAMETERS_SERVICE = f'{TASK_MANAGER_NODE}/list_parameters'
GET_PARAMETERS_SERVICE = f'{TASK_MANAGER_NODE}/get_parameters'
DEFAULT_TIMEOUT_SEC = 5.0
# How long a result that arrived before its task's ENDED event waits for it (for the stamps).
# The event is published first, so it is normally there already; this bounds a lost one.
ENDED_EVENT_GRACE_SEC = 2.0
# A service request is sent again after this long without a reply, then after twice as
# long, ...: a reply sent before DDS matched this client's reply reader is lost.
SERVICE_RETRY_SEC = 0.5

T = TypeVar('T')
T_contra = TypeVar('T_contra', contravariant=True)


class _End(Enum):
    """Put in an inbox to end the iteration over it."""

    OF_UPDATES = 'end of updates'
    """The `until` future of the iteration completed."""


# What the executor thread puts for one iterator of updates, and the end marker.
_Inbox: TypeAlias = queue.SimpleQueue[T | _End]


class _Listener(Protocol[T_contra]):
    """Where the executor thread puts updates of one kind (an inbox may take more kinds)."""

    def put(self, item: T_contra, /) -> None: ...


@dataclass(frozen=True)
class TaskResult:
    """How a task ended.

    The stamps are None when unknown: /task_manager/results and the ExecuteTask result carry
    none, so results from `results()` have none; a TaskHandle's result, `recent_results()`
    and the ENDED events of `task_events()` have them.
    """

    task_id: str
    task_name: str
    status: TaskStatus
    error_code: ErrorCode
    result: dict[str, Any]
    source: str = ''
    received_at: datetime | None = None
    """When the Task Manager received the task."""
    started_at: datetime | None = None
    """When it started on its server; None also when it never started."""
    ended_at: datetime | None = None
    paused: timedelta = timedelta(0)
    """How long it was paused (known with the stamps)."""

    @property
    def ok(self) -> bool:
        return self.status is TaskStatus.DONE

    @property
    def duration(self) -> timedelta | None:
        """How long it ran: from its start to its end, less the time it was paused; None if it
        never started or unknown."""
        if self.started_at is None or self.ended_at is None:
            return None
        return max(self.ended_at - self.started_at - self.paused, timedelta(0))

    @property
    def error_message(self) -> str:
        """Why the Task Manager refused or failed the task (its `error`), or ''."""
        error = self.result.get('error')
        return error if isinstance(error, str) else ''

    @classmethod
    def from_message(cls, message: Any, task_name: str = '', source: str = '') -> 'TaskResult':
        """From a TaskDoneResult, or an ExecuteTask result with the goal's name and source."""
        return cls(
            task_id=message.task_id,
            task_name=getattr(message, 'task_name', '') or task_name,
            status=TaskStatus(message.task_status),
            error_code=ErrorCode(message.error_code),
            result=json_object(message.task_result),
            source=getattr(message, 'source', '') or source,
        )

    def with_stamps_of(self, state: 'TaskState') -> 'TaskResult':
        """This result with the stamps (and time paused) of `state` (the same task's)."""
        return replace(
            self,
            received_at=state.received_at,
            started_at=state.started_at,
            ended_at=state.ended_at,
            paused=state.paused_before_end(),
        )


@dataclass(frozen=True)
class ActiveTaskInfo:
    """One entry of /task_manager/active_tasks (which carries no stamps: see TaskState)."""

    task_id: str
    task_name: str
    status: TaskStatus
    source: str


@dataclass(frozen=True)
class TaskState:
    """Everything known of one task at one moment: a TaskState message, with datetimes.

    Its first fields are those of ActiveTaskInfo, so it can stand in for one.
    """

    task_id: str
    task_name: str
    status: TaskStatus
    source: str
    error_code: ErrorCode = ErrorCode.NONE
    mission_id: str = ''
    """The id of the mission this task is a subtask of; '' when it is none's."""
    received_at: datetime | None = None
    started_at: datetime | None = None
    """When it started on its server; None while it has not (or never did)."""
    ended_at: datetime | None = None
    feedback: dict[str, Any] | None = None
    """The latest feedback; None before the first."""
    result: dict[str, Any] | None = None
    """The result once the task has ended; None before."""
    sequence: int = 0
    """Once ended: its number in the task history (only grows, never repeats); 0 before."""
    paused: timedelta = timedelta(0)
    """Time spent paused (the message's paused_sec)."""
    pauses: list[Pause] = field(default_factory=list)
    """Each pause, oldest first; the last is still open while the task is PAUSED."""

    @property
    def is_final(self) -> bool:
        return self.status.is_final

    def elapsed(self, now: datetime | None = None) -> timedelta | None:
        """How long it has run: from its start to its end, or to `now` (default: the present),
        less the time paused (the clock stops while it is paused).

        None if it has not started. The stamps are the Task Manager's wall clock.
        """
        if self.started_at is None:
            return None
        end = self.ended_at or now or datetime.now(UTC)
        return running_time(self.started_at, end, self.pauses, self.paused)

    def paused_before_end(self) -> timedelta:
        """Time paused, up to its end once ended (a task may end while paused)."""
        if self.ended_at is None:
            return self.paused
        return paused_time(self.pauses, self.paused, self.ended_at)

    def to_result(self) -> TaskResult:
        """The TaskResult of an ended task (of one still active: its result so far, `{}`)."""
        return TaskResult(
            task_id=self.task_id,
            task_name=self.task_name,
            status=self.status,
            error_code=self.error_code,
            result=self.result or {},
            source=self.source,
            received_at=self.received_at,
            started_at=self.started_at,
            ended_at=self.ended_at,
            paused=self.paused_before_end(),
        )

    @classmethod
    def from_message(cls, message: Any) -> 'TaskState':
        """From a task_manager_msgs/msg/TaskState."""
        return cls(
            task_id=message.task_id,
            task_name=message.task_name,
            status=TaskStatus(message.task_status),
            source=message.source,
            error_code=ErrorCode(message.error_code),
            mission_id=message.mission_id,
            received_at=datetime_of(message.received),
            started_at=datetime_of(message.started),
            ended_at=datetime_of(message.ended),
            feedback=json_object(message.feedback) if message.feedback else None,
            result=json_object(message.task_result) if message.task_result else None,
            sequence=message.sequence,
            paused=timedelta(seconds=max(message.paused_sec, 0.0)),
            pauses=parse_pauses(message.pauses),
        )


class TaskEventKind(StrEnum):
    """Which change of a task a TaskEvent reports."""

    RECEIVED = 'RECEIVED'
    """The Task Manager received the request (every request has one)."""
    STARTED = 'STARTED'
    """The task started on its server (not for a request refused before starting)."""
    FEEDBACK = 'FEEDBACK'
    """New feedback (at most `feedback_rate_hz` a second; the latest wins)."""
    PAUSED = 'PAUSED'
    """system/pause paused the task (its status is PAUSED; it is still active)."""
    RESUMED = 'RESUMED'
    """system/resume resumed the task (its status is IN_PROGRESS again)."""
    ENDED = 'ENDED'
    """The task ended (the last event of a task)."""


@dataclass(frozen=True)
class TaskEvent:
    """One message of /task_manager/task_events."""

    kind: TaskEventKind
    stamp: datetime
    """When the change happened (the Task Manager's wall clock)."""
    task: TaskState
    """The task's state just after the change."""

    @classmethod
    def from_message(cls, message: Any) -> 'TaskEvent':
        """From a task_manager_msgs/msg/TaskEvent."""
        stamp = datetime_of(message.stamp) or datetime.fromtimestamp(0, UTC)
        return cls(TaskEventKind(message.event), stamp, TaskState.from_message(message.task))


FeedbackCallback: TypeAlias = Callable[[dict[str, Any]], None]


class _Callback(Generic[T]):
    """Hands items to a user's callback; what the callback raises is logged, not spread."""

    def __init__(self, callback: Callable[[T], None], client: 'TaskManagerClient') -> None:
        self._callback = callback
        self._client = client

    def put(self, item: T, /) -> None:
        try:
            self._callback(item)
        except Exception:  # the callback boundary: the executor must go on
            self._client.node.get_logger().error(
                f'callback {self._callback!r} failed:\n{traceback.format_exc()}'
            )


class TaskHandle:
    """A task started by this client (or a subtask of a mission it started)."""

    def __init__(
        self, client: 'TaskManagerClient', task_id: str, task_name: str, source: str = ''
    ) -> None:
        self.task_id = task_id
        self.task_name = task_name
        self.source = source
        self.result_future: Future[TaskResult] = Future()
        """Completes with the TaskResult; awaitable from rclpy coroutines."""
        self.goal_id: bytes | None = None
        """The id of its ExecuteTask goal, once the Task Manager accepted it."""
        self.subtasks: list[TaskHandle] = []
        """Of a mission from `start_mission`: a handle per subtask, in order (else empty)."""
        self._client = client
        # The rest is guarded by the client's lock.
        self._state: TaskState | None = None
        self._feedback_listeners: list[_Listener[dict[str, Any]]] = []
        # A result that came before the task's ENDED event, and the timer that bounds the
        # wait for that event (see TaskManagerClient._complete)
        self._early_result: TaskResult | None = None
        self._early_result_timer: Timer | None = None

    @property
    def state(self) -> TaskState | None:
        """The task's latest state from /task_manager/task_events; None before its first event."""
        return self._state

    @property
    def latest_feedback(self) -> dict[str, Any] | None:
        """The task's latest feedback received; None before the first."""
        state = self._state
        return None if state is None else state.feedback

    def feedback(self, timeout_sec: float | None = None) -> Iterator[dict[str, Any]]:
        """The task's feedback: the latest already received, then each update, until it ends.

        Stops once the task has ended (after its last feedback), or after `timeout_sec`
        without feedback (None: no limit); `done()` tells which.
        """
        return self._client._feedback_of(self, timeout_sec)

    def on_feedback(self, callback: FeedbackCallback) -> None:
        """Call `callback(feedback)` with each feedback update of the task from now on.

        It runs on the client's executor thread, so it must return quickly and never wait on
        the client; an exception it raises is logged.
        """
        self._client._add_feedback_listener(self, _Callback(callback, self._client))

    def done(self) -> bool:
        return self.result_future.done()

    def result(self, timeout_sec: float | None = None) -> TaskResult:
        """Wait for the task to end; raises TaskTimeout after `timeout_sec` (None: no limit)."""
        ended = threading.Event()
        self.result_future.add_done_callback(lambda _: ended.set())
        if not ended.wait(timeout_sec) and not self.result_future.done():
            raise TaskTimeout(f'task {self.task_id} did not end within {timeout_sec} s')
        return result_of(self.result_future)

    def cancel(self, timeout_sec: float = DEFAULT_TIMEOUT_SEC) -> bool:
        """Cancel the task (as its client); True once the cancel request was accepted."""
        return self._client.cancel_own(self, timeout_sec)


class TaskManagerClient(PauseMethods, ScheduleMethods):
    """A client of the Task Manager with its own node, spun in a background thread.

    Use it as a context manager, or call `close()`.
    """

    def __init__(
        self, node_name: str = 'task_manager_client', timeout_sec: float = DEFAULT_TIMEOUT_SEC
    ) -> None:
        self.timeout_sec = timeout_sec
        self._context = Context()
        rclpy.init(context=self._context)
        self.node = rclpy.create_node(f'{node_name}_{uuid.uuid4().hex[:8]}', context=self._context)
        self._lock = threading.Condition()
        # key: task id, value: the handle of a task this client started and is waiting for
        self._handles_by_id: dict[str, TaskHandle] = {}
        self._active: list[ActiveTaskInfo] | None = None
        self._active_listeners: list[_Listener[list[ActiveTaskInfo]]] = []
        self._result_listeners: list[_Listener[TaskResult]] = []
        self._event_listeners: list[_Listener[TaskEvent]] = []
        self._connection_listeners: list[_Listener[bool]] = []
        self._follows_events = False
        # key: service name, value: this client's client of it, made on first use
        self._service_clients: dict[str, Client[Any, Any]] = {}
        self._matched: set[str] = set()
        # ExecuteTask through the action's own services: rclpy's ActionClient would also read
        # every status message, which lists every goal the node keeps (see action_services)
        self._execute_task = ActionServicesClient(self.node, ExecuteTask, EXECUTE_TASK_ACTION)
        self._subscribe(
            ActiveTaskArray, ACTIVE_TASKS_TOPIC, qos.LATEST_ACTIVE_TASKS, self._on_active
        )
        self._subscribe(TaskDoneResult, RESULTS_TOPIC, qos.RESULTS, self._on_result)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self.node)
        self._spin_thread = threading.Thread(target=self._spin, daemon=True)
        self._spin_thread.start()

    # ---- lifecycle ---------------------------------------------------------------------------

    def __enter__(self) -> 'TaskManagerClient':
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def close(self) -> None:
        self._executor.shutdown()
        self._spin_thread.join(timeout=self.timeout_sec)
        destroy_waitables(self.node)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self._context)

    def _spin(self) -> None:
        try:
            self._executor.spin()
        except Exception:  # the context is shutting down under us
            if self._context.ok():
                raise

    def _subscribe(
        self, msg_type: type, topic: str, profile: QoSProfile, callback: Callable[[Any], None]
    ) -> None:
        def matched(info: Any) -> None:
            with self._lock:
                was_connected = ACTIVE_TASKS_TOPIC in self._matched
                if info.current_count > 0:
                    self._matched.add(topic)
                else:
                    self._matched.discard(topic)
                connected = ACTIVE_TASKS_TOPIC in self._matched
                listeners = list(self._connection_listeners) if connected != was_connected else []
                self._lock.notify_all()
            for listener in listeners:
                listener.put(connected)

        self.node.create_subscription(
            msg_type,
            topic,
            callback,
            profile,
            event_callbacks=SubscriptionEventCallbacks(matched=matched),
        )

    def wait_until_available(
        self, timeout_sec: float | None = None, *, events: bool = False
    ) -> None:
        """Wait for the Task Manager's action server and topics; TaskManagerUnavailable if not.

        With `events`, also subscribe to /task_manager/task_events now and wait until it is
        connected, if the Task Manager publishes it (see `events_connected`).
        """
        timeout_sec = self.timeout_sec if timeout_sec is None else timeout_sec
        topics = {ACTIVE_TASKS_TOPIC, RESULTS_TOPIC}
        if events:  # first: DDS matches both ends of it while we wait for the rest
            self._subscribe_to_events()
        if not self._execute_task.wait_for_server(timeout_sec):
            raise TaskManagerUnavailable(
                f'no Task Manager answered at {EXECUTE_TASK_ACTION} within {timeout_sec} s'
            )
        with self._lock:
            if not self._lock.wait_for(lambda: topics <= self._matched, timeout_sec):
                raise TaskManagerUnavailable(
                    f'the Task Manager topics did not connect within {timeout_sec} s'
                )
        if events:
            self._follow_events(timeout_sec)

    @property
    def connected(self) -> bool:
        """Whether a Task Manager is there: its /task_manager/active_tasks reaches this client.

        It turns False at once when the node stops, and after DDS's lease duration when the
        node's process dies without stopping.
        """
        with self._lock:
            return ACTIVE_TASKS_TOPIC in self._matched

    def on_connection_change(self, callback: Callable[[bool], None]) -> Callable[[], None]:
        """Call `callback(connected)` each time `connected` changes; returns the unsubscribe.

        Like every callback of the client, it runs on the executor thread and must be quick.
        """
        return self._add_listener(self._connection_listeners, _Callback(callback, self))

    def on_task_event(self, callback: Callable[[TaskEvent], None]) -> Callable[[], None]:
        """Call `callback(event)` with every task event from now on; returns the unsubscribe.

        It runs on the executor thread: it must return quickly and never wait on the client.
        """
        self._subscribe_to_events()
        return self._add_listener(self._event_listeners, _Callback(callback, self))

    def _add_listener(
        self, listeners: list[_Listener[T]], listener: _Listener[T]
    ) -> Callable[[], None]:
        with self._lock:
            listeners.append(listener)
        return lambda: self._stop_listening(listeners, listener)

    @property
    def events_connected(self) -> bool:
        """Whether /task_manager/task_events reaches this client (it can be switched off)."""
        with self._lock:
            return TASK_EVENTS_TOPIC in self._matched

    def _follow_events(self, timeout_sec: float | None = None) -> None:
        """Subscribe to /task_manager/task_events (once); wait until connected, if published.

        The wait is skipped when no publisher of the events is known: the stream may be off.
        Our end connects first; the Task Manager's may take a moment more, so an event
        published just then can be missed (the stream is volatile): the handles cope.
        """
        self._subscribe_to_events()
        if self.node.count_publishers(TASK_EVENTS_TOPIC) == 0:
            return
        timeout_sec = self.timeout_sec if timeout_sec is None else timeout_sec
        with self._lock:
            self._lock.wait_for(lambda: TASK_EVENTS_TOPIC in self._matched, timeout_sec)

    def _subscribe_to_events(self) -> None:
        """Subscribe to /task_manager/task_events, once."""
        with self._lock:
            subscribe = not self._follows_events
            self._follows_events = True
        if subscribe:
            self._subscribe(TaskEventMessage, TASK_EVENTS_TOPIC, qos.TASK_EVENTS, self._on_event)

    # ---- starting tasks ---------------------------------------------------------------------

    def start_task(
        self,
        task_name: str,
        task_data: dict[str, Any] | str | None = None,
        *,
        task_id: str = '',
        source: str = 'python',
    ) -> TaskHandle:
        """Start a task; returns once the Task Manager has it (accepted, running or ended)."""
        return self._start(
            TaskHandle(self, task_id or str(uuid.uuid4()), task_name, source), task_data
        )

    def _start(self, handle: TaskHandle, task_data: dict[str, Any] | str | None) -> TaskHandle:
        """Send the goal of `handle` (and follow its events, and those of its subtasks)."""
        self._follow_events()
        with self._lock:
            for each in (handle, *handle.subtasks):
                self._handles_by_id[each.task_id] = each
        goal = ExecuteTask.Goal(
            task_id=handle.task_id,
            task_name=handle.task_name,
            source=handle.source,
            task_data=json_text(task_data),
        )
        if not self._send_goal(handle, goal):
            with self._lock:
                for each in (handle, *handle.subtasks):
                    self._handles_by_id.pop(each.task_id, None)
            raise TaskManagerUnavailable(
                f'the Task Manager did not answer the goal of {handle.task_name} within '
                f'{self.timeout_sec} s'
            )
        return handle

    def _send_goal(self, handle: TaskHandle, goal: ExecuteTask.Goal) -> bool:
        """Send the goal until the Task Manager answers (bounded); whether it did.

        A request sent just as DDS matches the node's reader can be lost, so the same goal
        (same goal id) is sent again after SERVICE_RETRY_SEC, then twice as long, ...: the
        node's action server refuses a goal id it already has, so it never runs twice.
        """
        deadline = time.monotonic() + self.timeout_sec
        retry_sec = SERVICE_RETRY_SEC
        goal_id, first = self._execute_task.send_goal(goal)
        requests = [first]

        def answered() -> bool:
            return handle.goal_id is not None or handle.done() or self._is_active(handle)

        first.add_done_callback(lambda f: self._on_goal_response(handle, goal_id, f, retried=False))
        with self._lock:
            while not answered() and (remaining := deadline - time.monotonic()) > 0:
                if self._lock.wait_for(answered, min(retry_sec, remaining)):
                    break
                retry_sec *= 2
                _, again = self._execute_task.send_goal(goal, goal_id)
                again.add_done_callback(
                    lambda f: self._on_goal_response(handle, goal_id, f, retried=True)
                )
                requests.append(again)
            done = answered()
        for request in requests:
            if not request.done():
                self._execute_task.forget_request(request)
        return done

    def run_task(
        self,
        task_name: str,
        task_data: dict[str, Any] | str | None = None,
        *,
        timeout_sec: float | None = None,
        **options: Any,
    ) -> TaskResult:
        """Start a task and wait for its result."""
        return self.start_task(task_name, task_data, **options).result(timeout_sec)

    def start_mission(
        self, subtasks: list[Subtask], *, task_id: str = '', source: str = 'python'
    ) -> tuple[TaskHandle, list[str]]:
        """Start system/mission; returns its handle and the subtask ids (generated if empty).

        The handle's `subtasks` are handles of the subtasks (feedback, state, result); one
        the mission never reached never ends.
        """
        subtask_ids = [s.task_id or str(uuid.uuid4()) for s in subtasks]
        data = mission_task_data(subtasks, subtask_ids)
        handle = TaskHandle(self, task_id or str(uuid.uuid4()), MISSION, source)
        handle.subtasks = [
            TaskHandle(self, subtask_id, s.task_name, MISSION_SOURCE)
            for s, subtask_id in zip(subtasks, subtask_ids, strict=True)
        ]
        return self._start(handle, data), subtask_ids

    def cancel_tasks(self, task_ids: list[str], *, source: str = 'python') -> TaskResult:
        """Cancel tasks by id through system/cancel_task (whoever started them)."""
        return self.run_task(CANCEL_TASK, {'cancelled_tasks': task_ids}, source=source)

    def stop(self, *, source: str = 'python') -> TaskResult:
        """system/stop: cancel every task declared with cancel_on_stop."""
        return self.run_task(STOP, {}, source=source)

    def cancel_own(self, handle: TaskHandle, timeout_sec: float) -> bool:
        """Cancel a task this client started, as its client (the task ends CANCELED)."""
        if handle.goal_id is None:
            return self.cancel_tasks([handle.task_id]).ok
        response = _wait(self._execute_task.cancel(handle.goal_id), timeout_sec)
        return response is not None and len(response.goals_canceling) > 0

    # ---- watching -----------------------------------------------------------------------------

    def active_tasks(self, timeout_sec: float | None = None) -> list[ActiveTaskInfo]:
        """The current active tasks (the latest /task_manager/active_tasks message)."""
        timeout_sec = self.timeout_sec if timeout_sec is None else timeout_sec
        with self._lock:
            if not self._lock.wait_for(lambda: self._active is not None, timeout_sec):
                raise TaskManagerUnavailable(f'no active task list within {timeout_sec} s')
            return list(self._active or [])

    def active_task_updates(
        self, timeout_sec: float | None = None, until: Future[Any] | None = None
    ) -> Iterator[list[ActiveTaskInfo]]:
        """Every active task list from now on.

        Stops after `timeout_sec` without an update (None: never), or once `until` completes.
        """
        inbox: _Inbox[list[ActiveTaskInfo]] = queue.SimpleQueue()
        with self._listening(self._active_listeners, inbox):
            yield from _drain(inbox, timeout_sec, until)

    def results(
        self, timeout_sec: float | None = None, until: Future[Any] | None = None
    ) -> Iterator[TaskResult]:
        """Every task result from now on; stops as active_task_updates does."""
        inbox: _Inbox[TaskResult] = queue.SimpleQueue()
        with self._listening(self._result_listeners, inbox):
            yield from _drain(inbox, timeout_sec, until)

    def updates(
        self, timeout_sec: float | None = None, until: Future[Any] | None = None
    ) -> Iterator[list[ActiveTaskInfo] | TaskResult]:
        """Active task lists and results, in the order they arrive; stops as above."""
        inbox: _Inbox[list[ActiveTaskInfo] | TaskResult] = queue.SimpleQueue()
        with (
            self._listening(self._active_listeners, inbox),
            self._listening(self._result_listeners, inbox),
        ):
            # annotated: mypy infers no T from `A | B | _End` against `T | _End` by itself
            arrivals: Iterator[list[ActiveTaskInfo] | TaskResult] = _drain(
                inbox, timeout_sec, until
            )
            yield from arrivals

    def task_events(
        self, timeout_sec: float | None = None, until: Future[Any] | None = None
    ) -> Iterator[TaskEvent]:
        """Every event of every task from this call on; stops as active_task_updates does.

        Events are kept from the call, not from the first `next()`: start the iterator, then
        the tasks whose events it must not miss.
        """
        self._follow_events()
        inbox: _Inbox[TaskEvent] = queue.SimpleQueue()
        self._add_listener(self._event_listeners, inbox)
        events = self._drain_then_stop(self._event_listeners, inbox, timeout_sec, until)
        # an iterator dropped before its first next() never runs its `finally`
        weakref.finalize(events, self._stop_listening, self._event_listeners, inbox)
        return events

    def _drain_then_stop(
        self,
        listeners: list[_Listener[T]],
        inbox: _Inbox[T],
        timeout_sec: float | None,
        until: Future[Any] | None,
    ) -> Iterator[T]:
        try:
            yield from _drain(inbox, timeout_sec, until)
        finally:
            self._stop_listening(listeners, inbox)

    def _stop_listening(self, listeners: list[_Listener[T]], inbox: _Listener[T]) -> None:
        with self._lock:
            if inbox in listeners:
                listeners.remove(inbox)

    def task_states(
        self, task_ids: Sequence[str] = (), timeout_sec: float | None = None
    ) -> list[TaskState]:
        """The current state of these tasks (active or ended and kept), or of every active one.

        Ids the Task Manager does not know are left out.
        """
        request = GetTaskStates.Request(task_ids=list(task_ids))
        response = self._call(GetTaskStates, GET_TASK_STATES_SERVICE, request, timeout_sec)
        return [TaskState.from_message(m) for m in response.tasks]

    def recent_results(self, max_results: int = 0) -> list[TaskResult]:
        """Results the Task Manager has kept (oldest first), including from before we started.

        With their stamps, from /task_manager/get_task_states.
        """
        request = GetTaskResults.Request(max_results=max_results)
        response = self._call(GetTaskResults, GET_TASK_RESULTS_SERVICE, request)
        results = [TaskResult.from_message(m) for m in response.results]
        if not results:
            return results
        # key: task id, value: its kept state (the latest task of that id)
        states = {s.task_id: s for s in self.task_states(sorted({r.task_id for r in results}))}
        return [
            result.with_stamps_of(state)
            if (state := states.get(result.task_id)) is not None and state.is_final
            else result
            for result in results
        ]

    def history(
        self,
        task_name: str = '',
        *,
        status: TaskStatus | str = '',
        source: str = '',
        mission_id: str = '',
        since: datetime | timedelta | None = None,
        until: datetime | None = None,
        after_sequence: int = 0,
        limit: int = 100,
        oldest_first: bool = False,
        timeout_sec: float | None = None,
    ) -> list[TaskState]:
        """Ended tasks from the Task Manager's durable history, newest first.

        Empty filters do not filter. `since`: ended at or after this moment, or within this
        long before now; `until`: ended at or before it. `after_sequence`: only tasks whose
        `sequence` is greater; with `oldest_first` the tasks come by sequence, so that a
        consumer can resume after the last one it saw. At most `limit` (1 to 10,000).
        """
        if not 1 <= limit <= HISTORY_QUERY_LIMIT_MAX:
            raise ValueError(f'limit must be from 1 to {HISTORY_QUERY_LIMIT_MAX}, got {limit}')
        if status and status not in FINAL_STATUSES:
            allowed = ', '.join(FINAL_STATUSES)
            raise ValueError(f'status must be one of {allowed} (or empty), got {status!r}')
        if isinstance(since, timedelta):
            since = datetime.now(UTC) - since
        request = QueryTaskHistory.Request(
            task_name=task_name,
            status=str(status),
            source=source,
            mission_id=mission_id,
            ended_after=Time() if since is None else stamp_of(since),
            ended_before=Time() if until is None else stamp_of(until),
            after_sequence=after_sequence,
            limit=limit,
            oldest_first=oldest_first,
        )
        response = self._call(QueryTaskHistory, QUERY_TASK_HISTORY_SERVICE, request, timeout_sec)
        return [TaskState.from_message(m) for m in response.tasks]

    def stats(
        self,
        task_name: str = '',
        *,
        source: str = '',
        mission_id: str = '',
        since: datetime | timedelta = timedelta(days=1),
        until: datetime | None = None,
        timeout_sec: float | None = None,
    ) -> list[TaskStats]:
        """Per task name: count, success rate, median and p95 duration of the tasks that ended
        in the range (default: the last 24 h), computed here from the whole history range.

        The history is read by sequence, 10,000 tasks per call (each call bounded by the
        timeout).
        """
        if isinstance(since, timedelta):
            since = datetime.now(UTC) - since  # one range for every page
        ended: list[TaskState] = []
        while True:
            page = self.history(
                task_name,
                source=source,
                mission_id=mission_id,
                since=since,
                until=until,
                after_sequence=ended[-1].sequence if ended else 0,
                limit=HISTORY_QUERY_LIMIT_MAX,
                oldest_first=True,
                timeout_sec=timeout_sec,
            )
            ended.extend(page)
            if len(page) < HISTORY_QUERY_LIMIT_MAX:
                return task_stats(ended)

    def declared_tasks(self) -> list[dict[str, Any]]:
        """The declared tasks and their properties, read from the node's parameters.

        Through this client's own two clients of the node's parameter services, made once:
        a parameter client per call (rclpy's AsyncParameterClient makes six) was never
        destroyed, and every process of the domain grew with each read.
        """
        listed = self._call(ListParameters, LIST_PARAMETERS_SERVICE, ListParameters.Request())
        names = list(listed.result.names)
        request = GetParameters.Request(names=names)
        got = self._call(GetParameters, GET_PARAMETERS_SERVICE, request)
        values = {n: parameter_value_to_python(v) for n, v in zip(names, got.values, strict=True)}
        return [*self._declared_in(values), *_system_tasks()]

    def _call(
        self, service_type: Any, name: str, request: Any, timeout_sec: float | None = None
    ) -> Any:
        """Call a Task Manager service that only reads; a lost reply is asked for again."""
        timeout_sec = self.timeout_sec if timeout_sec is None else timeout_sec
        deadline = time.monotonic() + timeout_sec
        with self._lock:
            client = self._service_clients.get(name)
            if client is None:
                client = self._service_clients[name] = self.node.create_client(service_type, name)
        if not client.wait_for_service(timeout_sec=timeout_sec):
            raise TaskManagerUnavailable(f'{name} is not available')
        answered = threading.Event()
        calls: list[Future[Any]] = []
        retry_sec = SERVICE_RETRY_SEC
        while not answered.is_set() and (remaining_sec := deadline - time.monotonic()) > 0:
            calls.append(client.call_async(request))
            calls[-1].add_done_callback(lambda _: answered.set())
            answered.wait(min(retry_sec, remaining_sec))
            retry_sec *= 2
        response = next((c.result() for c in calls if c.done() and c.result() is not None), None)
        for call in calls:
            client.remove_pending_request(call)
        if response is None:
            raise TaskManagerUnavailable(f'{name} did not answer within {timeout_sec} s')
        return response

    @staticmethod
    def _declared_in(values: dict[str, Any]) -> list[dict[str, Any]]:
        return [
            {
                'key': key,
                **{n[len(key) + 1 :]: v for n, v in values.items() if n.startswith(f'{key}.')},
            }
            for key in values.get('tasks') or []
        ]

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
            self._complete(handle, _refused(handle), final=True)
            return
        self._execute_task.get_result(goal_id).add_done_callback(
            lambda f: self._complete(
                handle,
                TaskResult.from_message(result_of(f).result, handle.task_name, handle.source),
            )
        )

    def _on_active(self, message: ActiveTaskArray) -> None:
        active = [
            ActiveTaskInfo(t.task_id, t.task_name, TaskStatus(t.task_status), t.source)
            for t in message.active_tasks
        ]
        with self._lock:
            self._active = active
            for listener in self._active_listeners:
                listener.put(active)
            self._lock.notify_all()

    def _on_result(self, message: TaskDoneResult) -> None:
        result = TaskResult.from_message(message)
        with self._lock:
            for listener in self._result_listeners:
                listener.put(result)
            handle = self._handles_by_id.get(result.task_id)
        if handle is not None and result.error_code is not ErrorCode.DUPLICATE_TASK_ID:
            self._complete(handle, result)

    def _on_event(self, message: TaskEventMessage) -> None:
        event = TaskEvent.from_message(message)
        task = event.task
        with self._lock:
            for listener in self._event_listeners:
                listener.put(event)
            handle = self._handles_by_id.get(task.task_id)
            if (
                handle is None
                or task.error_code is ErrorCode.DUPLICATE_TASK_ID
                or (event.kind is TaskEventKind.RECEIVED and handle._state is not None)
            ):  # not ours, or another request refused for using our task's id
                return
            handle._state = task
            feedback_listeners = (
                list(handle._feedback_listeners) if event.kind is TaskEventKind.FEEDBACK else []
            )
        if task.feedback is not None:
            for feedback_listener in feedback_listeners:  # unlocked: callbacks may use the client
                feedback_listener.put(task.feedback)
        if event.kind is TaskEventKind.ENDED:
            self._complete(handle, handle._early_result or task.to_result(), final=True)

    def _complete(self, handle: TaskHandle, result: TaskResult, final: bool = False) -> None:
        """End `handle` with `result`, and with the stamps of its task's events.

        A result that comes before the task's ENDED event (not `final`) waits for that event
        while the events reach us, at most ENDED_EVENT_GRACE_SEC: so the handle's result
        carries its end stamp, and its last feedback comes before its end.
        """
        with self._lock:
            if handle.done():
                return
            state = handle._state
            # the events reach us if one of this task's did, or the stream is connected (a
            # result can overtake the events of a short task: they queue behind others')
            events_reach_us = state is not None or TASK_EVENTS_TOPIC in self._matched
            if (
                not final
                and events_reach_us
                and result.error_code is not ErrorCode.DUPLICATE_TASK_ID
            ):
                if handle._early_result is None:
                    handle._early_result = result
                    handle._early_result_timer = self.node.create_timer(
                        ENDED_EVENT_GRACE_SEC, lambda: self._end_waiting_for_event(handle)
                    )
                return
            if state is not None:
                result = result.with_stamps_of(state)
            timer, handle._early_result_timer = handle._early_result_timer, None
            self._handles_by_id.pop(handle.task_id, None)
            if state is not None:  # subtasks the mission never reached will have no events
                for subtask in handle.subtasks:
                    if subtask._state is None:
                        self._handles_by_id.pop(subtask.task_id, None)
            handle.result_future.set_result(result)
            self._lock.notify_all()
        if timer is not None:
            self.node.destroy_timer(timer)

    def _end_waiting_for_event(self, handle: TaskHandle) -> None:
        """The ENDED event of `handle` did not come in time: end it with what it has."""
        if handle._early_result is not None:
            self._complete(handle, handle._early_result, final=True)

    def _feedback_of(
        self, handle: TaskHandle, timeout_sec: float | None
    ) -> Iterator[dict[str, Any]]:
        """See TaskHandle.feedback."""
        self._follow_events()
        inbox: _Inbox[dict[str, Any]] = queue.SimpleQueue()
        with self._lock:  # the latest first: no update can come between
            handle._feedback_listeners.append(inbox)
            if handle.latest_feedback is not None:
                inbox.put(handle.latest_feedback)
        try:
            yield from _drain(inbox, timeout_sec, handle.result_future)
        finally:
            with self._lock:
                handle._feedback_listeners.remove(inbox)

    def _add_feedback_listener(
        self, handle: TaskHandle, listener: _Listener[dict[str, Any]]
    ) -> None:
        """Have `listener` get the feedback updates of `handle` from now on."""
        self._follow_events()
        with self._lock:
            handle._feedback_listeners.append(listener)

    def _is_active(self, handle: TaskHandle) -> bool:
        return any(t.task_id == handle.task_id for t in self._active or [])

    @contextlib.contextmanager
    def _listening(self, listeners: list[_Listener[T]], inbox: _Listener[T]) -> Iterator[None]:
        """Have `inbox` get what is put to `listeners` until the block ends."""
        stop_listening = self._add_listener(listeners, inbox)
        try:
            yield
        finally:
            stop_listening()


def _drain(inbox: _Inbox[T], timeout_sec: float | None, until: Future[Any] | None) -> Iterator[T]:
    """What arrives in `inbox`, until `timeout_sec` passes without any or `until` completes."""
    if until is not None:
        until.add_done_callback(lambda _: inbox.put(_End.OF_UPDATES))
    while True:
        try:
            item = inbox.get(timeout=timeout_sec)
        except queue.Empty:
            return
        if item is _End.OF_UPDATES:
            return
        yield item


def _refused(handle: TaskHandle) -> TaskResult:
    return TaskResult(
        task_id=handle.task_id,
        task_name=handle.task_name,
        status=TaskStatus.ERROR,
        error_code=ErrorCode.TASK_START_FAILED,
        result={'error': f'{EXECUTE_TASK_ACTION} rejected the goal'},
        source=handle.source,
    )


def _wait(future: Future[T], timeout_sec: float) -> T | None:
    done = threading.Event()
    future.add_done_callback(lambda _: done.set())
    return future.result() if done.wait(timeout_sec) or future.done() else None


def _system_tasks() -> list[dict[str, Any]]:
    return [
        {
            'key': '',
            'task_name': spec.task_name,
            'msg_interface': str(spec.interface),
            'topic': '',
            'blocking': spec.blocking,
            'cancel_on_stop': spec.cancel_on_stop,
            'reentrant': spec.reentrant,
            'cancel_reported_as_success': spec.cancel_reported_as_success,
            'cancel_timeout': spec.cancel_timeout_sec,
        }
        for spec in SYSTEM_SPECS
    ]
