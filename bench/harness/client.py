"""The bench's side of every measurement: one node, a single-threaded executor in a thread.

Requests are sent from the main thread; their completion is time-stamped in the executor
thread's callbacks and signalled with threading events, so no wait polls or sleeps. Actions
are spoken through their services (see lean_action.py).
"""

import threading
import time
from collections.abc import Callable
from typing import Any, NamedTuple

from rclpy.serialization import deserialize_message
from rclpy.task import Future
from std_srvs.srv import Trigger
from test_msgs.action import Fibonacci

from bench.harness import config
from bench.harness.lean_action import LeanActionClient
from bench.harness.replies import BenchError, Reply, stamped, wait_reply
from task_manager.core.names import ACTIVE_TASKS_TOPIC, EXECUTE_TASK_ACTION, TASK_EVENTS_TOPIC
from task_manager.rclpy_tools import qos
from task_manager.testing.harness import RosHarness
from task_manager_msgs.action import ExecuteTask
from task_manager_msgs.msg import ActiveTaskArray, TaskEvent

BENCH_NODE_NAME = 'task_manager_bench'
BENCH_SOURCE = 'bench'


def execute_task_goal(task_name: str, task_data: str, task_id: str = '') -> ExecuteTask.Goal:
    return ExecuteTask.Goal(
        task_id=task_id, task_name=task_name, source=BENCH_SOURCE, task_data=task_data
    )


def task_status(reply: Reply) -> str:
    """The ExecuteTask status of a reply ('' when the goal was rejected or has no result)."""
    return reply.response.result.task_status if reply.response is not None else ''


def error_code(reply: Reply) -> str:
    return reply.response.result.error_code if reply.response is not None else ''


class Publication(NamedTuple):
    """One /task_manager/active_tasks message as the bench took it."""

    source_ns: int
    """When the node published it (DDS source timestamp)."""
    in_progress: int
    """How many tasks it lists IN_PROGRESS."""
    lists_done: bool
    """Whether it lists a task that ended DONE (the publication before its removal)."""


class ActiveTasksWatcher:
    """Follows /task_manager/active_tasks as serialized bytes, cheap even at 1,000 tasks.

    Our ids, names and source never contain 'IN_PROGRESS' or 'DONE', so counting those words
    in the raw message reads it without deserializing it.
    """

    def __init__(self, harness: RosHarness) -> None:
        self._changed = threading.Condition()
        self.latest = b''
        self._latest_at = 0.0
        self._history: list[Publication] = []
        self._node = harness.node
        self.subscription = harness.node.create_subscription(
            ActiveTaskArray, ACTIVE_TASKS_TOPIC, self._on_message, qos.ACTIVE_TASKS, raw=True
        )

    def _on_message(self, data: bytes, info: Any) -> None:
        with self._changed:
            self.latest = data
            self._latest_at = time.perf_counter()
            self._history.append(
                Publication(info['source_timestamp'], data.count(b'IN_PROGRESS'), b'DONE' in data)
            )
            self._changed.notify_all()

    def wait_until(self, predicate: Callable[[bytes], bool], timeout_sec: float, what: str) -> None:
        with self._changed:
            if not self._changed.wait_for(lambda: predicate(self.latest), timeout_sec):
                raise BenchError(f'{what}: not seen on {ACTIVE_TASKS_TOPIC} within {timeout_sec} s')

    def wait_in_progress(self, count: int, timeout_sec: float) -> float:
        """Wait until `count` tasks are in progress; return when that was published (perf_counter).

        Strictly, when the bench took the message: the bench's executor is idle meanwhile.
        """
        self.wait_until(
            lambda data: data.count(b'IN_PROGRESS') >= count, timeout_sec, f'{count} in progress'
        )
        return self._latest_at

    def wait_task_in_progress(self, task_id: str, timeout_sec: float) -> None:
        def in_progress(data: bytes) -> bool:
            if task_id.encode() not in data:
                return False
            message = deserialize_message(data, ActiveTaskArray)
            return any(
                t.task_id == task_id and t.task_status == 'IN_PROGRESS'
                for t in message.active_tasks
            )

        self.wait_until(in_progress, timeout_sec, f'{task_id} in progress')

    def take_history(self) -> list[Publication]:
        """The messages taken since the last call."""
        with self._changed:
            history = list(self._history)
            self._history.clear()
            return history

    def destroy(self) -> None:
        self._node.destroy_subscription(self.subscription)


# CDR: a 4-byte encapsulation header, then the fields, each aligned from the header's end
CDR_HEADER_BYTES = 4
CDR_LITTLE_ENDIAN = b'\x00\x01'
TIME_BYTES = 8  # builtin_interfaces/Time: int32 sec, uint32 nanosec


def _cdr_string(data: bytes, offset: int) -> tuple[str, int]:
    """The CDR string at `offset` (before alignment) and the offset just after it."""
    offset += -(offset - CDR_HEADER_BYTES) % 4
    length = int.from_bytes(data[offset : offset + 4], 'little')  # with its terminating NUL
    start = offset + 4
    return data[start : start + length - 1].decode(), start + length


def event_and_task_id(data: bytes) -> tuple[str, str]:
    """The kind (RECEIVED, ...) and task id of a serialized TaskEvent: its first fields.

    Read from the bytes: deserializing every event in Python would cost the bench's executor
    more than the node's publication costs the node.
    """
    if data[:2] != CDR_LITTLE_ENDIAN:
        message = deserialize_message(data, TaskEvent)
        return message.event, message.task.task_id
    event, offset = _cdr_string(data, CDR_HEADER_BYTES)
    offset += -(offset - CDR_HEADER_BYTES) % 4 + TIME_BYTES  # the event's stamp
    task_id, _ = _cdr_string(data, offset)
    return event, task_id


class SeenEvent(NamedTuple):
    """One /task_manager/task_events message as the bench took it."""

    event: str
    task_id: str
    at: float
    """When the bench took it (perf_counter)."""


class TaskEventsWatcher:
    """Follows /task_manager/task_events, reading each event's kind and task id only."""

    def __init__(self, harness: RosHarness) -> None:
        self._changed = threading.Condition()
        self._events: list[SeenEvent] = []
        self._node = harness.node
        self.subscription = harness.node.create_subscription(
            TaskEvent, TASK_EVENTS_TOPIC, self._on_message, qos.TASK_EVENTS, raw=True
        )

    def _on_message(self, data: bytes) -> None:
        event, task_id = event_and_task_id(data)
        with self._changed:
            self._events.append(SeenEvent(event, task_id, time.perf_counter()))
            self._changed.notify_all()

    def wait_until(
        self, predicate: Callable[[list[SeenEvent]], bool], timeout_sec: float, what: str
    ) -> None:
        """Wait until `predicate` holds for the events taken since the last `take`."""
        with self._changed:
            if not self._changed.wait_for(lambda: predicate(self._events), timeout_sec):
                raise BenchError(f'{what}: not seen on {TASK_EVENTS_TOPIC} within {timeout_sec} s')

    def wait_event(self, event: str, task_id: str, timeout_sec: float) -> None:
        self.wait_until(
            lambda events: any(e.event == event and e.task_id == task_id for e in events),
            timeout_sec,
            f'{event} of {task_id}',
        )

    def take(self) -> list[SeenEvent]:
        """The events taken since the last call."""
        with self._changed:
            events = self._events
            self._events = []
            return events

    def destroy(self) -> None:
        self._node.destroy_subscription(self.subscription)


class BenchClient:
    """Clients of the Task Manager and, for the baselines, of the same servers directly."""

    def __init__(self) -> None:
        self.harness = RosHarness(BENCH_NODE_NAME)
        node = self.harness.node
        self.execute_task = LeanActionClient(node, ExecuteTask, EXECUTE_TASK_ACTION)
        self.fibonacci = LeanActionClient(node, Fibonacci, config.DIRECT_FIBONACCI_TOPIC)
        self.hold = LeanActionClient(node, Fibonacci, config.DIRECT_HOLD_TOPIC)
        self.trigger = self._service(config.DIRECT_TRIGGER_TOPIC)
        self.release_goals = self._service(config.RELEASE_GOALS_TOPIC)
        self.release_calls = self._service(config.RELEASE_CALLS_TOPIC)
        self.release_feedback = self._service(config.RELEASE_FEEDBACK_TOPIC)

    def _service(self, topic: str) -> Any:
        return self.harness.node.create_client(Trigger, topic, qos_profile=qos.DEEP_RELIABLE)

    def wait_for_servers(self, timeout_sec: float) -> None:
        actions = (self.execute_task, self.fibonacci, self.hold)
        services = (self.trigger, self.release_goals, self.release_calls, self.release_feedback)
        for action in actions:
            if not action.wait_for_server(timeout_sec):
                raise BenchError(f'{action.action_name} not available within {timeout_sec} s')
        for service in services:
            if not service.wait_for_service(timeout_sec=timeout_sec):
                raise BenchError(f'{service.srv_name} not available within {timeout_sec} s')

    # ---- single requests -------------------------------------------------------------------

    def send_task(
        self, task_name: str, task_data: str, task_id: str = '', accepted: Future[Any] | None = None
    ) -> Future[Any]:
        return self.execute_task.send_goal(
            execute_task_goal(task_name, task_data, task_id), accepted
        )

    def send_fibonacci(self) -> Future[Any]:
        return self.fibonacci.send_goal(Fibonacci.Goal(order=0))

    def call(self, client: Any, request: Any) -> Future[Any]:
        """Call a service; the future's Reply is stamped when the response came."""
        replied: Future[Any] = Future()
        client.call_async(request).add_done_callback(stamped(replied))
        return replied

    def call_trigger(self, client: Any = None) -> Future[Any]:
        return self.call(client or self.trigger, Trigger.Request())

    def release(self, client: Any, what: str) -> None:
        wait_reply(self.call_trigger(client), what)

    def close(self) -> None:
        self.harness.close()
