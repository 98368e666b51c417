"""The adapter: one worker thread that owns the vehicle's state and handles, one at a time,
what arrives (inbound messages from paho's thread, task events from the client's executor
thread, the broker's return), and publishes the state on every change and at least every
`state_period_sec`.

Every inbound message is checked against the official schema first (schemas.py); one that
fails is never acted on and is reported in state.errors (validationError, naming the field).
"""

import logging
import queue
import threading
import time
from dataclasses import dataclass
from typing import Any

from task_manager.client import TaskEvent, TaskManagerClient
from task_manager_vda5050.factsheet import factsheet
from task_manager_vda5050.instant_actions import InstantActions
from task_manager_vda5050.link import Link
from task_manager_vda5050.mapping import Mapping
from task_manager_vda5050.order_plan import VALIDATION_ERROR, OrderRejectedError, Planner, Rejection
from task_manager_vda5050.orders import Orders
from task_manager_vda5050.schemas import read_inbound
from task_manager_vda5050.vehicle_state import VehicleState

LOG = logging.getLogger('task_manager_vda5050')
STATE_PERIOD_SEC = 30.0
PAYLOAD_EXCERPT = 200


@dataclass(frozen=True)
class Inbound:
    topic: str
    payload: bytes


class Connected:
    """The broker is back: the state and the factsheet go out again."""


class Stop:
    pass


Item = Inbound | TaskEvent | Connected | Stop


class Adapter:
    def __init__(
        self,
        client: TaskManagerClient,
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
        self._blocking_tasks = self._tasks_that_block_driving(client, mapping)
        self.planner = Planner(mapping, self._blocking_tasks.__contains__)
        self.orders = Orders(client, self.planner, self.state, mapping.position)
        self.instant = InstantActions(client, mapping, self.state, self.orders, self.publish)
        self._last_state: dict[str, Any] | None = None
        self._last_position: Any = None
        self._thread = threading.Thread(target=self._work, name='vda5050', daemon=True)

    @staticmethod
    def _tasks_that_block_driving(client: TaskManagerClient, mapping: Mapping) -> set[str]:
        """The declared tasks that cannot run beside the navigation: blocking ones, and
        those holding one of its resources."""
        declared = {task.get('task_name', ''): task for task in client.declared_tasks()}
        navigation = declared.get(mapping.navigation.task_name, {})
        driving = set(navigation.get('resources') or []) | {'@blocking'}
        return {
            name
            for name, task in declared.items()
            if task.get('blocking') or driving & set(task.get('resources') or [])
        }

    # ---- what other threads call ---------------------------------------------------------

    def start(self) -> None:
        self.client.on_task_event(self.items.put)
        self._thread.start()

    def stop(self, timeout_sec: float = 10.0) -> None:
        self.items.put(Stop())
        self._thread.join(timeout_sec)

    def on_message(self, topic: str, payload: bytes) -> None:
        self.items.put(Inbound(topic, payload))

    def on_connected(self) -> None:
        self.items.put(Connected())

    # ---- the worker ------------------------------------------------------------------------

    def _work(self) -> None:
        next_state = time.monotonic()
        while True:
            try:
                item = self.items.get(timeout=max(next_state - time.monotonic(), 0.0))
            except queue.Empty:
                item = None
            if isinstance(item, Stop):
                return
            try:
                self._handle(item)
            except Exception:  # the callback boundary: log it, the vehicle goes on
                LOG.exception('while handling %r', item)
            if item is None or self._state_changed():
                self.publish('state')
                next_state = time.monotonic() + self.state_period_sec

    def _handle(self, item: Item | None) -> None:
        if isinstance(item, Inbound):
            self._inbound(item)
        elif isinstance(item, TaskEvent):
            self.orders.on_event(item)
            self.instant.on_event(item)
        elif isinstance(item, Connected):
            self.publish('factsheet')
            self.publish('state')

    def _inbound(self, item: Inbound) -> None:
        document, invalid = read_inbound(item.topic, item.payload)
        if invalid is not None:
            where = f' at {invalid.field}' if invalid.field else ''
            words = f'{item.topic} not acted on: invalid{where}: {invalid.message}'
            LOG.warning('%s', words[: PAYLOAD_EXCERPT * 2])
            refs = [('topic', item.topic)]
            if invalid.field:
                refs.append(('field', invalid.field))
            self.state.add_error(
                Rejection(VALIDATION_ERROR, words[: PAYLOAD_EXCERPT * 2], tuple(refs))
            )
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
        self.link.publish('state', document)
        if 'agvPosition' in document and document['agvPosition'] != self._last_position:
            self._last_position = document['agvPosition']
            self.link.publish('visualization', {'agvPosition': document['agvPosition']})
