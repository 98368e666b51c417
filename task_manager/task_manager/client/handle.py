"""`TaskHandle`: a task this client started, and what the client tracks of it."""

import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeAlias

from rclpy.task import Future
from rclpy.timer import Timer

from task_manager.client.connection import DEFAULT_TIMEOUT_SEC
from task_manager.client.listeners import Listener
from task_manager.client.records import TaskResult, TaskState
from task_manager.core.bounds import check_wait_seconds
from task_manager.core.errors import TaskTimeout
from task_manager.rclpy_tools.action_services import ActionServicesClient
from task_manager.rclpy_tools.futures import result_of

FeedbackCallback: TypeAlias = Callable[[dict[str, Any]], None]


class HandleOwner(Protocol):
    """What a TaskHandle asks of the client that started it."""

    def feedback_of(
        self, handle: 'TaskHandle', timeout_sec: float | None
    ) -> Iterator[dict[str, Any]]: ...

    def add_feedback_callback(self, handle: 'TaskHandle', callback: FeedbackCallback) -> None: ...

    def cancel(self, handle: 'TaskHandle', timeout_sec: float) -> bool: ...


@dataclass
class Tracking:
    """What the client knows of one task between its events, guarded by the client's lock."""

    state: TaskState | None = None
    """The task's latest state from /task_manager/task_events; None before its first event."""
    feedback_listeners: list[Listener[dict[str, Any]]] = field(default_factory=list)
    early_result: TaskResult | None = None
    """A result that came before the task's ENDED event (see Tasks.complete)."""
    early_result_timer: Timer | None = None
    """The timer that bounds the wait for that event."""
    server: ActionServicesClient | None = None
    """The action its goal was sent to (ExecuteTask, or StartTask with options); None for a
    subtask, which has no goal of its own."""


class TaskHandle:
    """A task started by this client (or a subtask of a mission it started)."""

    def __init__(self, owner: HandleOwner, task_id: str, task_name: str, source: str = '') -> None:
        self.task_id = task_id
        self.task_name = task_name
        self.source = source
        self.result_future: Future[TaskResult] = Future()
        """Completes with the TaskResult; awaitable from rclpy coroutines."""
        self.goal_id: bytes | None = None
        """The id of its goal (ExecuteTask, or StartTask), once the Task Manager accepted it."""
        self.subtasks: list[TaskHandle] = []
        """Of a mission from `start_mission`: a handle per subtask, in order (else empty)."""
        self.tracking = Tracking()
        """The client's bookkeeping of the task (written on its executor thread)."""
        self._owner = owner

    @property
    def state(self) -> TaskState | None:
        """The task's latest state from /task_manager/task_events; None before its first event."""
        return self.tracking.state

    @property
    def latest_feedback(self) -> dict[str, Any] | None:
        """The task's latest feedback received; None before the first."""
        state = self.tracking.state
        return None if state is None else state.feedback

    def feedback(self, timeout_sec: float | None = None) -> Iterator[dict[str, Any]]:
        """The task's feedback: the latest already received, then each update, until it ends.

        Stops once the task has ended (after its last feedback), or after `timeout_sec`
        without feedback (None: no limit); `done()` tells which.
        """
        return self._owner.feedback_of(self, timeout_sec)

    def on_feedback(self, callback: FeedbackCallback) -> None:
        """Call `callback(feedback)` with each feedback update of the task from now on.

        It runs on the client's executor thread, so it must return quickly and never wait on
        the client; an exception it raises is logged.
        """
        self._owner.add_feedback_callback(self, callback)

    def done(self) -> bool:
        return self.result_future.done()

    def result(self, timeout_sec: float | None = None) -> TaskResult:
        """Wait for the task to end; raises TaskTimeout after `timeout_sec` (None: no limit)."""
        check_wait_seconds(timeout_sec)
        ended = threading.Event()
        self.result_future.add_done_callback(lambda _: ended.set())
        if not ended.wait(timeout_sec) and not self.result_future.done():
            raise TaskTimeout(f'task {self.task_id} did not end within {timeout_sec} s')
        return result_of(self.result_future)

    def cancel(self, timeout_sec: float = DEFAULT_TIMEOUT_SEC) -> bool:
        """Cancel the task (as its client); True once the cancel request was accepted."""
        return self._owner.cancel(self, timeout_sec)
