"""`SimulatedRobot`: one robot as its bridge is seen on the broker, without ROS (see the
package's docstring); `connect_all` connects many at once."""

import threading
import time
import uuid
from collections.abc import Sequence
from datetime import UTC, datetime, timedelta
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion
from paho.mqtt.reasoncodes import ReasonCode
from task_manager_mqtt.settings import DEFAULT_PREFIX
from task_manager_mqtt.topics import Topics

from task_manager.core.text.json_text import compact_json
from task_manager_console.simulation import documents
from task_manager_console.simulation.documents import Document, declared, iso
from task_manager_console.simulation.robot_loop import (
    FAILURE,
    TIMEOUT_SEC,
    RobotClient,
    RobotLoop,
)

EVENTS_PER_TASK = 3
"""Messages of a task from start to end (next_event): active_tasks twice, then its result."""


class SimulatedRobot:
    """One robot as its bridge is seen on the broker, without ROS; every call may come from
    any thread (the MQTT work runs on its RobotLoop's)."""

    def __init__(
        self,
        port: int,
        robot_id: str,
        password: str,
        *,
        prefix: str = DEFAULT_PREFIX,
        tasks: Sequence[str] = ('fib',),
        keepalive_sec: int = 10,
        loop: RobotLoop | None = None,
    ) -> None:
        """`loop`: the loop to run on (None: the process's shared one)."""
        self.robot_id = robot_id
        self.topics = Topics(prefix, robot_id)
        self.sequence = 0
        """Of the last result made."""
        self.declared = [declared(name) for name in tasks]
        self.published = 0
        """Messages sent at QoS 1 (through `publish` and the like)."""
        self.taken = 0
        """Of those, the ones the broker acknowledged."""
        self.refused = 0
        """Of those, the ones it refused (a PUBACK with a failure reason)."""
        self._loop = loop
        self._port = port
        self._keepalive_sec = keepalive_sec
        self._changed = threading.Condition()
        self._connected = False
        self._awaited: set[int] = set()
        """Message ids a caller waits for."""
        # key: a message id awaited, value: the broker's reason code
        self._acks: dict[int, int] = {}
        self._counting = False
        """Whether wait_taken waits (it is woken at each acknowledgement then)."""
        self._templates: dict[tuple[str, str], Document] = {}
        self._step = 0
        """Of next_event: the next message of the task it runs."""
        self._running: Document = {}
        self.mqtt = RobotClient(
            CallbackAPIVersion.VERSION2, client_id=robot_id, protocol=mqtt.MQTTv5
        )
        self.mqtt.username_pw_set(robot_id, password)
        self.mqtt.on_connect = self._on_connect
        self.mqtt.on_acknowledged = self._on_acknowledged
        will = self.connection_document('CONNECTIONBROKEN', task_manager_connected=False)
        self.mqtt.will_set(self.topics.connection, compact_json(will), qos=1, retain=True)

    @property
    def loop(self) -> RobotLoop:
        if self._loop is None:
            self._loop = RobotLoop.shared()
        return self._loop

    # ---- its connection -----------------------------------------------------------------------

    def connect(self) -> None:
        """Connect; then ONLINE, its declared tasks and no active task, as the bridge does."""
        self.start_connecting()
        self.wait_connected()
        self.announce()

    def start_connecting(self) -> None:
        """Open its connection (the broker's answer comes later: see wait_connected)."""

        def open_connection() -> None:
            self.mqtt.connect('127.0.0.1', self._port, keepalive=self._keepalive_sec)
            self.loop.attach(self.mqtt)

        self.loop.run(open_connection)

    def wait_connected(self, timeout_sec: float = TIMEOUT_SEC) -> None:
        with self._changed:
            if not self._changed.wait_for(lambda: self._connected, timeout_sec):
                raise TimeoutError(f'{self.robot_id}: no connection to the broker')

    def announce(self) -> None:
        """Its declared tasks, no active task and ONLINE, as its bridge once connected."""
        mids = self.loop.run(
            lambda: [
                self._publish(self.topics.tasks, self.declared_document(), retain=True),
                self._publish(self.topics.active_tasks, self.active_document([]), retain=True),
                self._publish(
                    self.topics.connection, self.connection_document('ONLINE'), retain=True
                ),
            ]
        )
        self._wait_acks(mids)

    def set_connection(self, state: str, task_manager_connected: bool = True) -> None:
        document = self.connection_document(state, task_manager_connected)
        self.publish(self.topics.connection, document, retain=True)

    def set_active(self, tasks: list[Document], omitted: int = 0) -> None:
        self.publish(self.topics.active_tasks, self.active_document(tasks, omitted), retain=True)

    def go_offline(self) -> None:
        """A clean stop: OFFLINE (retained), then a disconnection."""
        self.set_connection('OFFLINE', task_manager_connected=False)
        self.close()

    def vanish(self) -> None:
        """The connection dropped without a word: the broker publishes the last will."""

        def drop() -> None:
            sock = self.mqtt.socket()
            self.loop.detach(self.mqtt)
            if sock is not None:
                sock.close()

        self.loop.run(drop)

    def close(self) -> None:
        def disconnect() -> None:
            self.loop.detach(self.mqtt)
            self.mqtt.disconnect()

        if self._loop is not None:  # else it never connected
            self.loop.run(disconnect)

    # ---- its documents ------------------------------------------------------------------------

    def connection_document(self, state: str, task_manager_connected: bool = True) -> Document:
        return documents.connection(self.robot_id, state, task_manager_connected)

    def declared_document(self) -> Document:
        return documents.task_list(self.declared)

    def active_document(self, tasks: list[Document], omitted: int = 0) -> Document:
        return documents.task_list(tasks, omitted)

    def task(self, task_name: str = 'fib', status: str = 'DONE', **fields: Any) -> Document:
        """The next result's Task document (its sequence the next one), ended now."""
        self.sequence += 1
        ended = datetime.now(UTC)
        task_id = fields.pop('task_id', f'{self.robot_id}-{self.sequence}-{uuid.uuid4().hex[:6]}')
        return {
            **self._template(task_name, status),
            'task_id': task_id,
            'received': iso(ended - timedelta(seconds=1)),
            'started': iso(ended - timedelta(seconds=1)),
            'ended': iso(ended),
            'sequence': self.sequence,
            **fields,
        }

    def running(self, task_id: str, task_name: str = 'fib') -> Document:
        """The Task document of a task running now (as in `active_tasks`)."""
        now = iso(datetime.now(UTC))
        started = {'task_id': task_id, 'received': now, 'started': now}
        return {**self._template(task_name, 'IN_PROGRESS'), **started}

    def _template(self, task_name: str, status: str) -> Document:
        """documents.task_template, made once per name and status."""
        key = (task_name, status)
        if key not in self._templates:
            self._templates[key] = documents.task_template(task_name, status)
        return self._templates[key]

    # ---- what it sends ------------------------------------------------------------------------

    def send_results(self, count: int, wait: bool = True, **fields: Any) -> list[Document]:
        """Send `count` results in order (QoS 1); with `wait`, until the broker took them all."""
        tasks = [self.task(**fields) for _ in range(count)]
        mids = self.loop.run(
            lambda: [self._publish(self.topics.result, task, awaited=wait) for task in tasks]
        )
        if wait:
            self._wait_acks(mids)
        return tasks

    def next_event(self) -> bool:
        """On the loop's thread: send the next message of a robot that runs its declared tasks
        one after another, as its bridge shows them: a task's start (active with it running),
        its end (active without it), its result; without waiting. Whether it was a result."""
        step = self._step
        self._step = (step + 1) % EVENTS_PER_TASK
        if step == 0:
            task_name = self.declared[self.sequence % len(self.declared)]['task_name']
            self._running = self.running(str(uuid.uuid4()), task_name)
            self._publish(self.topics.active_tasks, self.active_document([self._running]),
                          retain=True, awaited=False)  # fmt: skip
        elif step == 1:
            self._publish(self.topics.active_tasks, self.active_document([]), retain=True,
                          awaited=False)  # fmt: skip
        else:
            result = self.task(self._running['task_name'], task_id=self._running['task_id'])
            self._publish(self.topics.result, result, awaited=False)
        return step == EVENTS_PER_TASK - 1

    def publish(
        self, topic: str, payload: Document | bytes, retain: bool = False, wait: bool = True
    ) -> int:
        """Publish at QoS 1 (a document as JSON, bytes as they are); its message id. With
        `wait`, until the broker took it (RuntimeError if it refused it)."""
        mid = self.loop.run(lambda: self._publish(topic, payload, retain=retain, awaited=wait))
        if wait:
            self._wait_acks([mid])
        return mid

    def _publish(
        self, topic: str, payload: Document | bytes, *, retain: bool = False, awaited: bool = True
    ) -> int:
        """On the loop's thread: publish at QoS 1; its message id (awaited: its ack is kept)."""
        data = payload if isinstance(payload, bytes) else compact_json(payload).encode()
        mid = self.mqtt.publish_qos1(topic, data, retain)
        self.published += 1
        if awaited:
            self._awaited.add(mid)
        self.loop.touch(self.mqtt)
        return mid

    def wait_taken(self, count: int, timeout_sec: float = TIMEOUT_SEC) -> None:
        """Wait until the broker has acknowledged `count` of its messages in all."""
        with self._changed:
            self._counting = True
            try:
                if not self._changed.wait_for(lambda: self.taken >= count, timeout_sec):
                    message = f'{self.robot_id}: {self.taken} messages taken, not {count}'
                    raise TimeoutError(message)
            finally:
                self._counting = False

    def _wait_acks(self, mids: list[int]) -> None:
        with self._changed:
            done = self._changed.wait_for(lambda: all(m in self._acks for m in mids), TIMEOUT_SEC)
            if not done:
                raise TimeoutError(f'{self.robot_id}: the broker did not take its messages')
            failed = [f'0x{self._acks[m]:02x}' for m in mids if self._acks[m] >= FAILURE]
            for mid in mids:
                self._acks.pop(mid, None)
        if failed:
            raise RuntimeError(f'{self.robot_id}: the broker refused messages: {failed[:3]}')

    # ---- on the loop's thread -----------------------------------------------------------------

    def _on_connect(self, _: mqtt.Client, __: Any, ___: Any, reason: ReasonCode, ____: Any) -> None:
        with self._changed:
            self._connected = not reason.is_failure
            self._changed.notify_all()

    def _on_acknowledged(self, mid: int, reason: int) -> None:
        with self._changed:
            self.taken += 1
            if reason >= FAILURE:
                self.refused += 1
            if mid in self._awaited:
                self._awaited.discard(mid)
                self._acks[mid] = reason
                self._changed.notify_all()
            elif self._counting:
                self._changed.notify_all()


def connect_all(robots: Sequence[SimulatedRobot], timeout_sec: float = TIMEOUT_SEC) -> None:
    """Connect many robots at once (each then announces itself, as connect does)."""
    for robot in robots:
        robot.start_connecting()
    deadline = time.monotonic() + timeout_sec
    for robot in robots:
        robot.wait_connected(max(deadline - time.monotonic(), 0.0))
    for robot in robots:
        robot.announce()
