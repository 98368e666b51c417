"""`TaskManagerClient`: start, watch and cancel tasks of a running Task Manager from Python.

The client generates every task id itself and takes a task's outcome from whichever comes
first, the ExecuteTask result or the task's message on /task_manager/results, so a lost
reply on the network never leaves a script waiting: every wait is bounded.
"""

import contextlib
import json
import queue
import threading
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from enum import Enum
from typing import Any, Protocol, TypeAlias, TypeVar

import rclpy
from rclpy.action import ActionClient
from rclpy.action.client import ClientGoalHandle
from rclpy.client import Client
from rclpy.context import Context
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile
from rclpy.task import Future
from task_manager_msgs.action import ExecuteTask
from task_manager_msgs.msg import ActiveTaskArray, TaskDoneResult
from task_manager_msgs.srv import GetTaskResults

from task_manager.core.errors import TaskManagerUnavailable, TaskTimeout
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.ros import qos
from task_manager.ros.cleanup import destroy_waitables
from task_manager.ros.futures import result_of
from task_manager.ros.system.specs import SYSTEM_SPECS

EXECUTE_TASK_ACTION = '/task_manager/execute_task'
ACTIVE_TASKS_TOPIC = '/task_manager/active_tasks'
RESULTS_TOPIC = '/task_manager/results'
GET_TASK_RESULTS_SERVICE = '/task_manager/get_task_results'
TASK_MANAGER_NODE = '/task_manager'
DEFAULT_TIMEOUT_SEC = 5.0

T = TypeVar('T')
T_contra = TypeVar('T_contra', contravariant=True)
# The generated message classes are untyped (no stubs), so their type arguments are Any.
_ExecuteTaskGoalHandle: TypeAlias = ClientGoalHandle[
    ExecuteTask.Goal, ExecuteTask.Result, ExecuteTask.Feedback
]


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
    """How a task ended."""

    task_id: str
    task_name: str
    status: TaskStatus
    error_code: ErrorCode
    result: dict[str, Any]
    source: str = ''

    @property
    def ok(self) -> bool:
        return self.status is TaskStatus.DONE

    @property
    def error_message(self) -> str:
        """Why the Task Manager refused or failed the task (its `error`), or ''."""
        error = self.result.get('error')
        return error if isinstance(error, str) else ''

    @classmethod
    def from_message(cls, message: Any, task_name: str = '', source: str = '') -> 'TaskResult':
        """From a TaskDoneResult, or an ExecuteTask result with the goal's name and source."""
        try:
            result = json.loads(message.task_result or '{}')
        except json.JSONDecodeError:
            result = {'raw': message.task_result}
        if not isinstance(result, dict):
            result = {'raw': message.task_result}
        return cls(
            task_id=message.task_id,
            task_name=getattr(message, 'task_name', '') or task_name,
            status=TaskStatus(message.task_status),
            error_code=ErrorCode(message.error_code),
            result=result,
            source=getattr(message, 'source', '') or source,
        )


@dataclass(frozen=True)
class ActiveTaskInfo:
    """One entry of /task_manager/active_tasks."""

    task_id: str
    task_name: str
    status: TaskStatus
    source: str


@dataclass(frozen=True)
class Subtask:
    """One subtask of a mission; `task_data` is a dict or a JSON string."""

    task_name: str
    task_data: dict[str, Any] | str = field(default_factory=dict)
    allow_skipping: bool = False
    task_id: str = ''


def _json(data: dict[str, Any] | str | None) -> str:
    return data if isinstance(data, str) else json.dumps(data or {})


class TaskHandle:
    """A task started by this client."""

    def __init__(
        self, client: 'TaskManagerClient', task_id: str, task_name: str, source: str = ''
    ) -> None:
        self.task_id = task_id
        self.task_name = task_name
        self.source = source
        self.result_future: Future[TaskResult] = Future()
        """Completes with the TaskResult; awaitable from rclpy coroutines."""
        self.goal_handle: _ExecuteTaskGoalHandle | None = None
        self._client = client

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


class TaskManagerClient:
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
        self._matched: set[str] = set()
        self._action_client: ActionClient[
            ExecuteTask.Goal, ExecuteTask.Result, ExecuteTask.Feedback
        ] = ActionClient(
            self.node,
            ExecuteTask,
            EXECUTE_TASK_ACTION,
            goal_service_qos_profile=qos.DEEP_RELIABLE,
            result_service_qos_profile=qos.DEEP_RELIABLE,
            cancel_service_qos_profile=qos.DEEP_RELIABLE,
        )
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
                if info.current_count > 0:
                    self._matched.add(topic)
                self._lock.notify_all()

        self.node.create_subscription(
            msg_type,
            topic,
            callback,
            profile,
            event_callbacks=SubscriptionEventCallbacks(matched=matched),
        )

    def wait_until_available(self, timeout_sec: float | None = None) -> None:
        """Wait for the Task Manager's action server and topics; TaskManagerUnavailable if not."""
        timeout_sec = self.timeout_sec if timeout_sec is None else timeout_sec
        topics = {ACTIVE_TASKS_TOPIC, RESULTS_TOPIC}
        if not self._action_client.wait_for_server(timeout_sec=timeout_sec):
            raise TaskManagerUnavailable(
                f'no Task Manager answered at {EXECUTE_TASK_ACTION} within {timeout_sec} s'
            )
        with self._lock:
            if not self._lock.wait_for(lambda: topics <= self._matched, timeout_sec):
                raise TaskManagerUnavailable(
                    f'the Task Manager topics did not connect within {timeout_sec} s'
                )

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
        handle = TaskHandle(self, task_id or str(uuid.uuid4()), task_name, source)
        with self._lock:
            self._handles_by_id[handle.task_id] = handle
        goal = ExecuteTask.Goal(
            task_id=handle.task_id, task_name=task_name, source=source, task_data=_json(task_data)
        )
        goal_future = self._action_client.send_goal_async(goal)
        goal_future.add_done_callback(lambda f: self._on_goal_response(handle, f))
        with self._lock:
            if not self._lock.wait_for(
                lambda: handle.goal_handle is not None or handle.done() or self._is_active(handle),
                self.timeout_sec,
            ):
                self._handles_by_id.pop(handle.task_id, None)
                raise TaskManagerUnavailable(
                    f'the Task Manager did not answer the goal of {task_name} within '
                    f'{self.timeout_sec} s'
                )
        return handle

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
        """Start system/mission; returns its handle and the subtask ids (generated if empty)."""
        subtask_ids = [s.task_id or str(uuid.uuid4()) for s in subtasks]
        data = {
            'subtasks': [
                {
                    'task_id': subtask_id,
                    'task_name': s.task_name,
                    'task_data': _json(s.task_data),
                    'allow_skipping': s.allow_skipping,
                }
                for s, subtask_id in zip(subtasks, subtask_ids, strict=True)
            ]
        }
        return self.start_task('system/mission', data, task_id=task_id, source=source), subtask_ids

    def cancel_tasks(self, task_ids: list[str], *, source: str = 'python') -> TaskResult:
        """Cancel tasks by id through system/cancel_task (whoever started them)."""
        return self.run_task('system/cancel_task', {'cancelled_tasks': task_ids}, source=source)

    def stop(self, *, source: str = 'python') -> TaskResult:
        """system/stop: cancel every task declared with cancel_on_stop."""
        return self.run_task('system/stop', {}, source=source)

    def cancel_own(self, handle: TaskHandle, timeout_sec: float) -> bool:
        """Cancel a task this client started, as its client (the task ends CANCELED)."""
        if handle.goal_handle is None:
            return self.cancel_tasks([handle.task_id]).ok
        response = _wait(handle.goal_handle.cancel_goal_async(), timeout_sec)
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

    def recent_results(self, max_results: int = 0) -> list[TaskResult]:
        """Results the Task Manager has kept (oldest first), including from before we started."""
        client: Client[GetTaskResults.Request, GetTaskResults.Response] = self.node.create_client(
            GetTaskResults, GET_TASK_RESULTS_SERVICE
        )
        try:
            if not client.wait_for_service(timeout_sec=self.timeout_sec):
                raise TaskManagerUnavailable(f'{GET_TASK_RESULTS_SERVICE} is not available')
            request = GetTaskResults.Request(max_results=max_results)
            response = _wait(client.call_async(request), self.timeout_sec)
            if response is None:
                raise TaskManagerUnavailable(f'{GET_TASK_RESULTS_SERVICE} did not answer')
            return [TaskResult.from_message(m) for m in response.results]
        finally:
            self.node.destroy_client(client)

    def declared_tasks(self) -> list[dict[str, Any]]:
        """The declared tasks and their properties, read from the node's parameters."""
        parameters = AsyncParameterClient(self.node, TASK_MANAGER_NODE)
        if not parameters.wait_for_services(timeout_sec=self.timeout_sec):
            raise TaskManagerUnavailable('the Task Manager parameter services are not available')
        listed = _wait(parameters.list_parameters(), self.timeout_sec)
        if listed is None:
            raise TaskManagerUnavailable('the Task Manager did not list its parameters')
        names = list(listed.result.names)
        got = _wait(parameters.get_parameters(names), self.timeout_sec)
        if got is None:
            raise TaskManagerUnavailable('the Task Manager did not send its parameters')
        values = {n: parameter_value_to_python(v) for n, v in zip(names, got.values, strict=True)}
        return [*self._declared_in(values), *_system_tasks()]

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

    def _on_goal_response(self, handle: TaskHandle, future: Future[_ExecuteTaskGoalHandle]) -> None:
        goal_handle = result_of(future)
        with self._lock:
            handle.goal_handle = goal_handle
            self._lock.notify_all()
        goal_handle.get_result_async().add_done_callback(
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

    def _complete(self, handle: TaskHandle, result: TaskResult) -> None:
        with self._lock:
            self._handles_by_id.pop(handle.task_id, None)
            if not handle.result_future.done():
                handle.result_future.set_result(result)
            self._lock.notify_all()

    def _is_active(self, handle: TaskHandle) -> bool:
        return any(t.task_id == handle.task_id for t in self._active or [])

    @contextlib.contextmanager
    def _listening(self, listeners: list[_Listener[T]], inbox: _Listener[T]) -> Iterator[None]:
        """Have `inbox` get what is put to `listeners` until the block ends."""
        with self._lock:
            listeners.append(inbox)
        try:
            yield
        finally:
            with self._lock:
                listeners.remove(inbox)


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
