"""The client's link to the Task Manager: its own context and node, spun by an executor in a
background thread; the topics it subscribes to and which of them a publisher reaches."""

import threading
import time
import traceback
import uuid
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rclpy.subscription import MessageInfo
from rclpy.type_description_service import START_TYPE_DESCRIPTION_SERVICE_PARAM
from task_manager_msgs.msg import TaskEvent as TaskEventMessage
from task_manager_msgs.msg import TaskEventArray

from task_manager.client.listeners import Listeners
from task_manager.client.records import TaskEvent
from task_manager.core.bounds import check_wait_seconds
from task_manager.core.names import ACTIVE_TASKS_TOPIC, TASK_EVENT_BATCHES_TOPIC
from task_manager.rclpy_tools import qos
from task_manager.rclpy_tools.cleanup import destroy_waitables
from task_manager.rclpy_tools.log import NodeLog
from task_manager.rclpy_tools.spin_thread import SpinThread
from task_manager.rclpy_tools.wakeless_executor import WakelessExecutor

DEFAULT_TIMEOUT_SEC = 5.0
# A request is sent again after this long without a reply, then after twice as long, ...:
# a reply sent before DDS matched this client's reply reader is lost.
SERVICE_RETRY_SEC = 0.5
GOAL_RESEND_WITHIN_SEC = 8.0
"""A goal not answered is sent again (same goal id) only this long after its first sending: the
node keeps an ended goal's id 10 s (its action server's result_timeout) and refuses it while
it does; a goal sent again after the node forgot it would run a second time."""
LOST_EVENTS_LOG_SEC = 10.0
"""The most often the client logs that task events went missing (with the count since)."""

# Where a message stands in its publisher's stream: the writer, and the message's number in it.
Place = tuple[bytes, int]


def place_of(info: MessageInfo) -> Place:
    """The writer's id and the message's sequence number (its source time where the middleware
    numbers nothing: the writer's own clock, so still ordered within one writer)."""
    gid = info['publisher_gid']
    sequence = info['publication_sequence_number']
    return (
        bytes(gid['data']) if gid else b'',
        info['source_timestamp'] if sequence is None else sequence,
    )


def client_node(node_name: str, context: Context) -> Node:
    """A node of a client, `<node_name>_<8 hex digits>`, in `context`: without services of its
    own (a client's node has no parameters to serve: its 7 parameter services and its type
    description service were 8 of the 20 entities of every wait set)."""
    return rclpy.create_node(
        f'{node_name}_{uuid.uuid4().hex[:8]}',
        context=context,
        start_parameter_services=False,
        parameter_overrides=[Parameter(START_TYPE_DESCRIPTION_SERVICE_PARAM, value=False)],
    )


class Connection:
    """The client's context, node and executor thread, and what reaches it.

    `lock` is the client's one lock: every helper of the client guards its state with it, and
    waits on it for what the executor thread brings.
    """

    def __init__(self, node_name: str, timeout_sec: float) -> None:
        self.timeout_sec = timeout_sec
        """How long a call waits when not told (the client's `timeout_sec`)."""
        self._context = Context()
        rclpy.init(context=self._context)
        self.node = client_node(node_name, self._context)
        self.lock = threading.Condition()
        self.changes = Listeners[bool](self.lock)
        """Who is told each change of `connected`."""
        self.reaching = Listeners[frozenset[str]](self.lock)
        """Who is told the keys of the readers a publisher reaches, at each change of them."""
        self._matched: set[str] = set()
        self._executor = WakelessExecutor(context=self._context)
        self._spinner = SpinThread(self._executor, self.node, 'task-manager-client')
        self._closed = False

    def start(self) -> None:
        """Spin the node in the background thread (once the helpers have made their ends)."""
        self._executor.add_node(self.node)
        self._spinner.start()

    def close(self) -> None:
        """Stop the executor thread, then destroy the node and the context. A thread still in a
        callback after `timeout_sec` keeps them: destroying a node under the thread that spins
        it can crash the process; they go with the process. Closing again does nothing."""
        if self._closed:
            return
        self._closed = True
        if not self._spinner.stop(self.timeout_sec):
            NodeLog.of(self.node).warning(
                f"the client's executor thread did not end within {self.timeout_sec:g} s; "
                'its node is left to the end of the process'
            )
            return
        self._executor.shutdown()
        destroy_waitables(self.node)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self._context)

    def subscribe(
        self,
        msg_type: type,
        topic: str,
        profile: QoSProfile,
        callback: Callable[..., None],
        key: str = '',
        with_info: bool = False,
        raw: bool = False,
        on_reached: Callable[[bool], None] | None = None,
    ) -> None:
        """Subscribe to a topic of the Task Manager, noting whether a publisher reaches us
        (under `key`, the topic unless told: a second reader of a topic has a key of its own).
        `callback(message)`, or `callback(message, info)` `with_info` (rclpy's MessageInfo);
        `raw`, the message is its serialized bytes (to read with rclpy's deserialize_message).
        `on_reached(connected)`, each time a publisher reaches the reader after none did, with
        whether the active list reached this client already then (on the executor thread).

        What `callback` raises is logged, not spread: it would end the executor thread, and
        with it every call of the client.
        """
        key = key or topic

        def guarded(message: Any, info: MessageInfo) -> None:
            try:
                if with_info:
                    callback(message, info)
                else:
                    callback(message)
            except Exception:  # the callback boundary: the executor thread must go on
                NodeLog.of(self.node).error(
                    f'a message of {topic} could not be handled:\n{traceback.format_exc()}'
                )

        def matched(info: Any) -> None:
            with self.lock:
                was_connected = ACTIVE_TASKS_TOPIC in self._matched
                reached = info.current_count > 0 and key not in self._matched
                if info.current_count > 0:
                    self._matched.add(key)
                else:
                    self._matched.discard(key)
                connected = ACTIVE_TASKS_TOPIC in self._matched
                listeners = self.changes.copy() if connected != was_connected else []
                self.reaching.put(frozenset(self._matched))
                self.lock.notify_all()
            for listener in listeners:
                listener.put(connected)
            if reached and on_reached is not None:
                on_reached(was_connected)

        self.node.create_subscription(
            msg_type,
            topic,
            guarded,
            profile,
            raw=raw,
            # the node's writers are made with the QoS asked: no incompatible-QoS handlers
            event_callbacks=SubscriptionEventCallbacks(
                matched=matched, use_default_callbacks=False
            ),
        )

    def is_matched(self, key: str) -> bool:
        """Whether a publisher reaches this client's reader of `key` (a topic, see subscribe)."""
        with self.lock:
            return key in self._matched

    def matched(self) -> frozenset[str]:
        """The keys of the readers a publisher reaches now (see subscribe)."""
        with self.lock:
            return frozenset(self._matched)

    def wait_matched(self, keys: set[str], timeout_sec: float | None) -> bool:
        """Wait until a publisher reaches each reader of `keys`; whether one did."""
        check_wait_seconds(timeout_sec)
        with self.lock:
            return self.lock.wait_for(lambda: keys <= self._matched, timeout_sec)

    @property
    def connected(self) -> bool:
        """Whether /task_manager/active_tasks reaches this client (see the client's)."""
        return self.is_matched(ACTIVE_TASKS_TOPIC)


class EventFeed:
    """The task events, as /task_manager/task_event_batches carries them (the node's events
    of a turn in one message, in order): subscribed to once, on first use, and who listens.

    The middleware numbers each writer's messages one after the other: a number skipped is a
    batch the reader overwrote before the client took it (a client that fell behind the node
    by more than the reader's depth, 1,000 batches). The events after it are delivered, then
    `lost` is told how many batches went missing, and the client logs it (at most once in
    LOST_EVENTS_LOG_SEC). It is told 0 (not known) when the events reach the client after the
    node's active list did (see _on_reached).
    """

    def __init__(
        self, connection: Connection, on_message: Callable[[TaskEventMessage], None]
    ) -> None:
        self._connection = connection
        self._on_message = on_message
        self._subscribed = False
        self.listeners = Listeners[TaskEvent](connection.lock)
        """Who gets every event (put by whoever `on_message` is: the client's task tracker)."""
        self.lost = Listeners[int](connection.lock)
        """Who is told how many batches went missing, each time some did."""
        # key: a writer of the batches, value: the number of the last batch taken from it
        self._last_numbers: dict[bytes, int] = {}
        self._lost_unlogged = 0
        self._lost_logged_at = -LOST_EVENTS_LOG_SEC

    @property
    def connected(self) -> bool:
        return self._connection.is_matched(TASK_EVENT_BATCHES_TOPIC)

    def subscribe(self) -> None:
        """Subscribe to the events, once."""
        with self._connection.lock:
            subscribe = not self._subscribed
            self._subscribed = True
        if subscribe:
            self._connection.subscribe(
                TaskEventArray,
                TASK_EVENT_BATCHES_TOPIC,
                qos.TASK_EVENTS,
                self._on_batch,
                with_info=True,
                on_reached=self._on_reached,
            )

    def _on_batch(self, batch: TaskEventArray, info: MessageInfo) -> None:
        missed = self._missed(info)
        for message in batch.events:
            self._on_message(message)
        if missed:
            self._log_lost(missed)
            self.lost.put(missed)

    def _on_reached(self, connected: bool) -> None:
        """The events reach this client again, or for the first time, after the node's active
        list did (a node started, or started again): what the node published between reached
        no one here, and no number shows it (a new writer numbers from 1). Who follows the
        events is told, as of a loss of an unknown number of batches (0), to read again what
        it keeps of them; measured, the events' reader matched 11-18 ms after the active
        list's. Not logged: nothing here says that an event came in that moment."""
        if connected:
            self.lost.put(0)

    def _missed(self, info: MessageInfo) -> int:
        """How many batches of this one's writer came between the last one taken from it and
        it (0 from a writer not seen before, or where the middleware numbers nothing)."""
        if info['publication_sequence_number'] is None:
            return 0
        writer, number = place_of(info)
        last = self._last_numbers.get(writer)
        self._last_numbers[writer] = number
        return 0 if last is None else max(number - last - 1, 0)

    def _log_lost(self, missed: int) -> None:
        self._lost_unlogged += missed
        now = time.monotonic()
        if now - self._lost_logged_at < LOST_EVENTS_LOG_SEC:
            return
        NodeLog.of(self._connection.node).warning(
            f'{self._lost_unlogged} batch(es) of task events went missing: this client fell '
            'behind the Task Manager and its reader overwrote them; who follows the events is '
            'told (on_events_lost)'
        )
        self._lost_unlogged, self._lost_logged_at = 0, now

    def follow(self, timeout_sec: float | None = None) -> None:
        """Subscribe (once); wait until connected, if the Task Manager publishes the events.

        The wait is skipped when no publisher of the events is known: the stream may be off.
        Our end connects first; the Task Manager's may take a moment more, so an event
        published just then can be missed (the stream is volatile): the handles cope.
        """
        self.subscribe()
        if self._connection.node.count_publishers(TASK_EVENT_BATCHES_TOPIC) == 0:
            return
        timeout_sec = self._connection.timeout_sec if timeout_sec is None else timeout_sec
        self._connection.wait_matched({TASK_EVENT_BATCHES_TOPIC}, timeout_sec)
