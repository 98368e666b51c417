"""Tools of the console's tests and benchmarks: a real PostgreSQL server, and a light simulated
robot that speaks its bridge's MQTT protocol (no ROS), to run many on one machine."""

import json
import shutil
import tempfile
import threading
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion
from paho.mqtt.reasoncodes import ReasonCode
from task_manager_mqtt.settings import DEFAULT_PREFIX
from task_manager_mqtt.topics import Topics

from task_manager_console.fleet import Change, Fleet
from task_manager_console.store.local_postgres import PostgresServer

TIMEOUT_SEC = 20.0
CONSOLE_USER = 'console'
"""The console's account on the tests' broker."""
ROBOTS = ('robot1', 'robot2', 'robot3')
Document = dict[str, Any]


@contextmanager
def postgres_server() -> Iterator[PostgresServer]:
    """A PostgreSQL server in a new temporary folder (under /tmp, where the `postgres` user
    reaches it when root starts it), stopped and removed at the end."""
    folder = Path(tempfile.mkdtemp(prefix='fleet-postgres-'))
    server = PostgresServer(folder)
    try:
        server.start()
        yield server
    finally:
        server.stop()
        shutil.rmtree(folder, ignore_errors=True)


def declared(task_name: str, blocking: bool = False) -> Document:
    """A DeclaredTask document."""
    return {
        'task_name': task_name,
        'msg_interface': 'test_msgs/action/Fibonacci',
        'blocking': blocking,
    }


class SimulatedRobot:
    """One robot as its bridge is seen on the broker, without ROS: its connection (and the
    bridge's last will), its declared and active tasks (retained) and its results (QoS 1, in
    sequence order), each document as the bridge sends it."""

    def __init__(
        self,
        port: int,
        robot_id: str,
        password: str,
        *,
        prefix: str = DEFAULT_PREFIX,
        tasks: Sequence[str] = ('fib',),
        keepalive_sec: int = 10,
    ) -> None:
        self.robot_id = robot_id
        self.topics = Topics(prefix, robot_id)
        self.sequence = 0
        """Of the last result sent."""
        self.declared = [declared(name) for name in tasks]
        self._port = port
        self._keepalive_sec = keepalive_sec
        self._changed = threading.Condition()
        # key: message id, value: the broker's answer
        self._acks: dict[int, ReasonCode] = {}
        self._connected = False
        self.mqtt = mqtt.Client(
            CallbackAPIVersion.VERSION2, client_id=robot_id, protocol=mqtt.MQTTv5
        )
        self.mqtt.username_pw_set(robot_id, password)
        self.mqtt.max_inflight_messages_set(1000)
        self.mqtt.max_queued_messages_set(0)
        self.mqtt.on_connect = self._on_connect
        self.mqtt.on_publish = self._on_publish
        will = self.connection_document('CONNECTIONBROKEN', task_manager_connected=False)
        self.mqtt.will_set(self.topics.connection, json.dumps(will), qos=1, retain=True)

    def connect(self) -> None:
        """Connect; then ONLINE, its declared tasks and no active task, as the bridge does."""
        self.mqtt.connect('127.0.0.1', self._port, keepalive=self._keepalive_sec)
        self.mqtt.loop_start()
        with self._changed:
            if not self._changed.wait_for(lambda: self._connected, TIMEOUT_SEC):
                raise TimeoutError(f'{self.robot_id}: no connection to the broker')
        self.publish(self.topics.tasks, {'timestamp': _now(), 'tasks': self.declared}, retain=True)
        self.set_active([])
        self.set_connection('ONLINE')

    def set_connection(self, state: str, task_manager_connected: bool = True) -> None:
        document = self.connection_document(state, task_manager_connected)
        self.publish(self.topics.connection, document, retain=True)

    def set_active(self, tasks: list[Document], omitted: int = 0) -> None:
        document = {'timestamp': _now(), 'tasks': tasks, 'omitted': omitted}
        self.publish(self.topics.active_tasks, document, retain=True)

    def go_offline(self) -> None:
        """A clean stop: OFFLINE (retained), then a disconnection."""
        self.set_connection('OFFLINE', task_manager_connected=False)
        self.close()

    def vanish(self) -> None:
        """The connection dropped without a word: the broker publishes the last will."""
        sock = self.mqtt.socket()
        if sock is not None:
            sock.close()
        self.mqtt.loop_stop()

    def close(self) -> None:
        self.mqtt.disconnect()
        self.mqtt.loop_stop()

    def connection_document(self, state: str, task_manager_connected: bool = True) -> Document:
        return {
            'robot_id': self.robot_id,
            'connection_state': state,
            'timestamp': _now(),
            'task_manager_connected': task_manager_connected,
            'version': '1',
            'dead_letters': 0,
        }

    def task(self, task_name: str = 'fib', status: str = 'DONE', **fields: Any) -> Document:
        """The next result's Task document (its sequence the next one)."""
        self.sequence += 1
        ended = datetime.now(UTC)
        return {
            'task_id': fields.pop(
                'task_id', f'{self.robot_id}-{self.sequence}-{uuid.uuid4().hex[:6]}'
            ),
            'task_name': task_name,
            'source': 'CLOUD',
            'status': status,
            'error_code': '',
            'error_message': '',
            'mission_id': '',
            'received': (ended - timedelta(seconds=1)).isoformat(),
            'started': (ended - timedelta(seconds=1)).isoformat(),
            'ended': ended.isoformat(),
            'duration_sec': 1.0,
            'result': {'sequence': [0, 1, 1]},
            'sequence': self.sequence,
            'priority': 0,
            'attempt': 1,
            'decisions': [],
            **fields,
        }

    def send_results(self, count: int, wait: bool = True, **fields: Any) -> list[Document]:
        """Send `count` results in order (QoS 1); with `wait`, until the broker took them all."""
        tasks = [self.task(**fields) for _ in range(count)]
        infos = [self.publish(self.topics.result, task, wait=False) for task in tasks]
        if wait:
            self._wait_acks([info.mid for info in infos])
        return tasks

    def publish(
        self, topic: str, payload: Document | bytes, retain: bool = False, wait: bool = True
    ) -> mqtt.MQTTMessageInfo:
        """Publish at QoS 1 (a document as JSON, bytes as they are)."""
        data = payload if isinstance(payload, bytes) else json.dumps(payload).encode()
        info = self.mqtt.publish(topic, data, qos=1, retain=retain)
        if wait:
            self._wait_acks([info.mid])
        return info

    def _wait_acks(self, mids: list[int]) -> None:
        with self._changed:
            done = self._changed.wait_for(lambda: all(m in self._acks for m in mids), TIMEOUT_SEC)
            if not done:
                raise TimeoutError(f'{self.robot_id}: the broker did not take its messages')
            failed = [str(self._acks.pop(m)) for m in mids if self._acks[m].is_failure]
            for mid in mids:
                self._acks.pop(mid, None)
        if failed:
            raise RuntimeError(f'{self.robot_id}: the broker refused messages: {failed[:3]}')

    def _on_connect(self, _: mqtt.Client, __: Any, ___: Any, reason: ReasonCode, ____: Any) -> None:
        with self._changed:
            self._connected = not reason.is_failure
            self._changed.notify_all()

    def _on_publish(self, _: mqtt.Client, __: Any, mid: int, reason: ReasonCode, ___: Any) -> None:
        with self._changed:
            self._acks[mid] = reason
            self._changed.notify_all()


def _now() -> str:
    return datetime.now(UTC).isoformat()


class Results:
    """The results a Fleet stores, as it stores them (its `on_change`), to wait on."""

    def __init__(self, fleet: Fleet) -> None:
        self.stored: list[dict[str, Any]] = []
        self._changed = threading.Condition()
        fleet.on_change(self._on_change)

    def _on_change(self, change: Change) -> None:
        if change.result is not None:
            with self._changed:
                self.stored.append(change.result)
                self._changed.notify_all()

    def wait(self, count: int, timeout_sec: float = TIMEOUT_SEC) -> list[dict[str, Any]]:
        """Wait until `count` results are stored; them."""
        with self._changed:
            if not self._changed.wait_for(lambda: len(self.stored) >= count, timeout_sec):
                raise AssertionError(f'{len(self.stored)} results stored, not {count}')
            return list(self.stored)


def wait_until(condition: Callable[[], object], timeout_sec: float, what: str) -> None:
    """Check `condition` until it holds (every 50 ms: what it reads, a database another
    process writes, has no events to wait on); AssertionError naming `what` if it does not
    within `timeout_sec`."""
    deadline = time.monotonic() + timeout_sec
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f'{what}: not within {timeout_sec} s')
        time.sleep(0.05)
