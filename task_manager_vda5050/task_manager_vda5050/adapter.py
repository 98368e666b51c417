"""The adapter: one worker thread that owns the vehicle's state and handles, one at a time,
what arrives (inbound messages from paho's thread, task events from the client's executor
thread, the broker's return), and publishes the state on every change and at least every
`state_period_sec`.

Every inbound message is checked at the door first (inbound.py: its size, depth, bounds,
the official schema, a header naming this vehicle); one that fails is never acted on and is
reported in state.errors (validationError, naming the field). What waits to be handled is
bounded too (Backlog); state is shortened to fit the broker's limit before it is sent.
"""

import logging
import queue
import threading
import time
import traceback
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from task_manager.client import TaskEvent, TaskEventKind, TaskManagerClient, TaskState
from task_manager.core.bounds import REASON_MAX_CHARACTERS, VDA5050_WAITING_MAX_BYTES, cut_text
from task_manager.core.errors import TaskManagerError, TaskManagerUnavailable
from task_manager.core.status import TaskStatus
from task_manager_vda5050.inbound import read_inbound
from task_manager_vda5050.link import Link
from task_manager_vda5050.mapping import Mapping
from task_manager_vda5050.orders.instant_actions import InstantActions
from task_manager_vda5050.orders.plan import (
    VALIDATION_ERROR,
    OrderRejectedError,
    Planner,
    Rejection,
)
from task_manager_vda5050.orders.running import SOURCE, Orders
from task_manager_vda5050.state.factsheet import factsheet
from task_manager_vda5050.state.fitting import shortened
from task_manager_vda5050.state.vehicle_state import VehicleState

LOG = logging.getLogger('task_manager_vda5050')
STATE_PERIOD_SEC = 30.0
MESSAGES_DROPPED = 'messagesDropped'
"""The errorType of the error saying how many inbound messages were dropped unread."""
ORDER_LOST = 'orderLost'
"""The errorType of the error saying the adapter started while tasks of an earlier adapter of
the vehicle ran (cancelled)."""


@dataclass(frozen=True)
class Inbound:
    topic: str
    payload: bytes

    def __str__(self) -> str:
        text = self.payload.decode(errors='replace')
        return f'{self.topic} message of {len(self.payload)} bytes: {cut_text(text)}'


class Backlog:
    """The bytes of the inbound messages received and not yet handled (paho's thread adds,
    the worker takes away): a message that would take them over `max_bytes` is dropped, and
    counted."""

    def __init__(self, max_bytes: int = VDA5050_WAITING_MAX_BYTES) -> None:
        self.max_bytes = max_bytes
        self._lock = threading.Lock()
        self._bytes = 0
        self._dropped = 0

    def admit(self, size: int) -> bool:
        """Whether a message of `size` bytes may wait (else it is counted as dropped)."""
        with self._lock:
            if self._bytes + size > self.max_bytes:
                self._dropped += 1
                return False
            self._bytes += size
            return True

    def handled(self, size: int) -> int:
        """A message of `size` bytes taken off; how many were dropped since the last call."""
        with self._lock:
            self._bytes -= size
            dropped, self._dropped = self._dropped, 0
            return dropped


class Connected:
    """The broker is back: the state and the factsheet go out again."""


class EventsLost:
    """Task events went missing (the client fell too far behind the Task Manager): the tasks
    followed are read again."""


class Stop:
    pass


Item = Inbound | TaskEvent | Connected | EventsLost | Stop
CAUGHT_UP = 'read again: task events of it went missing'
"""The reason of an event that stands in for lost ones (see standing_in)."""
CATCH_UP_AGAIN_SEC = 2.0
"""How long after a read of the tasks followed failed (the Task Manager unavailable or slow
to answer) the adapter reads them again, until one succeeds."""


def standing_in(task: TaskState) -> TaskEvent | None:
    """The event that brings a follower of `task` to its state now, its own events lost: ENDED
    once it has ended, else PAUSED or STARTED; None while it waits to start."""
    if task.is_final:
        kind = TaskEventKind.ENDED
    elif task.status is TaskStatus.PAUSED:
        kind = TaskEventKind.PAUSED
    elif task.status is TaskStatus.IN_PROGRESS:
        kind = TaskEventKind.STARTED
    else:
        return None
    return TaskEvent(kind, datetime.now(UTC), task, CAUGHT_UP)


class Adapter:
    def __init__(
        self,
        client: TaskManagerClient,
        declared: list[dict[str, Any]],
        link: Link,
        mapping: Mapping,
        state_period_sec: float = STATE_PERIOD_SEC,
    ) -> None:
        self.client = client
        self.link = link
        self.mapping = mapping
        self.state_period_sec = state_period_sec
        self.state = VehicleState()
        self.state.battery.update(mapping.reported.get('batteryState') or {})
        self.state.safety.update(mapping.reported.get('safetyState') or {})
        self.state.operating_mode = mapping.reported.get('operatingMode', 'AUTOMATIC')
        self.items: queue.SimpleQueue[Item] = queue.SimpleQueue()
        self._blocking_tasks = self._tasks_that_block_driving(declared, mapping)
        self.planner = Planner(mapping, self._blocking_tasks.__contains__)
        self.orders = Orders(client, self.planner, self.state, mapping.position)
        self.instant = InstantActions(client, mapping, self.state, self.orders, self.publish)
        self.backlog = Backlog()
        self._last_state: dict[str, Any] | None = None
        self._last_position: Any = None
        self._shortening = False
        """Whether the last state sent was shortened (said once in the log, until one fits)."""
        self._thread = threading.Thread(target=self._work, name='vda5050', daemon=True)
        self._catch_up_at: float | None = None
        """When to read the tasks followed again (a read failed), or None."""

    @staticmethod
    def _tasks_that_block_driving(declared: list[dict[str, Any]], mapping: Mapping) -> set[str]:
        """The declared tasks that cannot run beside the navigation: blocking ones, and
        those holding one of its resources."""
        by_name = {task.get('task_name', ''): task for task in declared}
        navigation = by_name.get(mapping.navigation.task_name, {})
        driving = set(navigation.get('resources') or []) | {'@blocking'}
        return {
            name
            for name, task in by_name.items()
            if task.get('blocking') or driving & set(task.get('resources') or [])
        }

    # ---- what other threads call ---------------------------------------------------------

    def start(self) -> None:
        self.client.on_task_event(self.items.put)
        self.client.on_events_lost(lambda _batches: self.items.put(EventsLost()))
        self._cancel_tasks_left_over()
        self._thread.start()

    def _cancel_tasks_left_over(self) -> None:
        """Cancel the vehicle's tasks that an earlier adapter started (it ended, or was started
        again by its supervisor, while its order ran): their order is known to no one now, and
        a vehicle must not move under an order its state does not show. state.errors says so,
        and the master sends the order again."""
        try:
            left_over = [s.task_id for s in self.client.task_states() if s.source == SOURCE]
        except TaskManagerUnavailable as error:
            LOG.warning('the tasks of an earlier adapter could not be read: %s', error)
            return
        if not left_over:
            return
        words = (
            f'{len(left_over)} tasks of an order this adapter does not know ran in the Task '
            f"Manager as it started (an earlier adapter's): cancelled; send the order again"
        )
        LOG.warning('%s: %s', words, ', '.join(cut_text(t) for t in left_over[:10]))
        self.state.add_error(Rejection(ORDER_LOST, cut_text(words, REASON_MAX_CHARACTERS)))
        try:
            self.client.cancel_tasks(left_over, source=SOURCE)
        except TaskManagerError as error:
            LOG.error('the tasks of an earlier adapter could not be cancelled: %s', error)

    def stop(self, timeout_sec: float = 10.0) -> None:
        self.items.put(Stop())
        self._thread.join(timeout_sec)

    def on_message(self, topic: str, payload: bytes) -> None:
        if self.backlog.admit(len(payload)):
            self.items.put(Inbound(topic, payload))

    def on_connected(self) -> None:
        self.items.put(Connected())

    # ---- the worker ------------------------------------------------------------------------

    def _work(self) -> None:
        next_state = time.monotonic()
        while True:
            wake_at = min(next_state, self._catch_up_at or next_state)
            try:
                item = self.items.get(timeout=max(wake_at - time.monotonic(), 0.0))
            except queue.Empty:
                item = None
            if isinstance(item, Stop):
                return
            if item is None and self._catch_up_at and time.monotonic() >= self._catch_up_at:
                item = EventsLost()  # the read that failed, again
            try:
                self._handle(item)
            except Exception as error:  # the callback boundary: log it, the vehicle goes on
                LOG.error(
                    'while handling %s: %s\n%s',
                    cut_text(str(item)),
                    cut_text(f'{type(error).__name__}: {error}'),
                    ''.join(traceback.format_tb(error.__traceback__)).rstrip(),
                )
            if item is None or self._state_changed():
                self.publish('state')
                next_state = time.monotonic() + self.state_period_sec

    def _handle(self, item: Item | None) -> None:
        if isinstance(item, Inbound):
            self._inbound(item)
        elif isinstance(item, TaskEvent):
            self.orders.on_event(item)
            self.instant.on_event(item)
        elif isinstance(item, EventsLost):
            self._catch_up()
        elif isinstance(item, Connected):
            self.publish('factsheet')
            self.publish('state')

    def _catch_up(self) -> None:
        """The state now of each task followed stands in for its lost events, in the order
        their events would have come (an order's steps, the tasks beside, its mission, then
        the instant actions): one that ended is handled as ENDED, once."""
        followed = [*self.orders.followed(), *self.instant.followed()]
        LOG.warning('task events went missing: reading the %d tasks followed again', len(followed))
        try:
            found = self.client.task_states(followed)
        except TaskManagerUnavailable as error:
            LOG.warning('%s: reading them again in %g s', error, CATCH_UP_AGAIN_SEC)
            self._catch_up_at = time.monotonic() + CATCH_UP_AGAIN_SEC
            return
        self._catch_up_at = None
        states = {s.task_id: s for s in found}
        for task_id in followed:
            task = states.get(task_id)
            event = standing_in(task) if task is not None else None
            if event is not None:
                self._handle(event)

    def _inbound(self, item: Inbound) -> None:
        if dropped := self.backlog.handled(len(item.payload)):
            words = (
                f'{dropped} inbound messages dropped unread: more than '
                f'{self.backlog.max_bytes} bytes of them waited to be handled'
            )
            LOG.warning('%s', words)
            self.state.add_error(Rejection(MESSAGES_DROPPED, words))
        document, invalid = read_inbound(item.topic, item.payload, self.link.vehicle)
        if invalid is not None:
            where = f' at {invalid.field}' if invalid.field else ''
            words = f'{item.topic} not acted on: invalid{where}: {invalid.message}'
            words = cut_text(words, REASON_MAX_CHARACTERS)
            LOG.warning('%s', words)
            refs = [('topic', item.topic)]
            if invalid.field:
                refs.append(('field', invalid.field))
            self.state.add_error(Rejection(VALIDATION_ERROR, words, tuple(refs)))
            return
        assert document is not None
        if item.topic == 'order':
            try:
                self.orders.receive(document)
            except OrderRejectedError as rejected:
                LOG.warning('order %s rejected: %s', document['orderId'], rejected)
                self.state.add_error(rejected.rejection)
        else:
            self.instant.receive(document)

    def _state_changed(self) -> bool:
        document = self.state.document()
        changed = document != self._last_state
        return changed

    def publish(self, topic: str) -> None:
        """Send the state, the factsheet or the visualization now (worker thread only)."""
        if topic == 'factsheet':
            self.link.publish(
                'factsheet', factsheet(self.mapping, self._blocking_tasks.__contains__)
            )
            return
        document = self.state.document()
        self._last_state = document
        fields, left_out = shortened(document, self.link.room())
        if left_out and not self._shortening:
            LOG.warning(
                'state shortened to fit the %d bytes the broker takes; left out: %s '
                '(said once, until a state fits again)',
                self.link.largest_payload,
                left_out,
            )
        self._shortening = bool(left_out)
        self.link.publish('state', fields)
        if 'agvPosition' in document and document['agvPosition'] != self._last_position:
            self._last_position = document['agvPosition']
            self.link.publish('visualization', {'agvPosition': document['agvPosition']})
