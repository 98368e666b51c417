"""Helpers of the bridge's tests and benchmarks: the bridge run as users run it, and a bare
MQTT client that sends what the FleetClient never would."""

import sys
import threading
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion
from paho.mqtt.reasoncodes import ReasonCode

from task_manager.testing.process import TEST_NICENESS, NodeProcess, nice_option
from task_manager_mqtt.broker import READY_LINE, MosquittoBroker

BRIDGE_EXECUTABLE = str(Path(sys.executable).with_name('task-manager-mqtt'))
CONNECTED_LINE = r'connected to the broker'
START_TIMEOUT_SEC = 20.0
TIMEOUT_SEC = 15.0
ROBOT = 'robot1'
"""The robot of the tests with one robot."""
TESTER = 'tester'
"""A second cloud account of the tests' broker: a bare client beside the FleetClient."""


class BridgeProcess(NodeProcess):
    """`task-manager-mqtt --robot-id R --broker-url U --state-file F [--nice N] [args]`."""

    def __init__(
        self,
        robot_id: str,
        broker_url: str,
        state_file: Path,
        *args: str,
        wait: bool = True,
        nice: int | None = TEST_NICENESS,
    ) -> None:
        """`wait`: until it is connected to the broker; `nice`: None for the bridge's default."""
        command = [
            BRIDGE_EXECUTABLE,
            '--robot-id',
            robot_id,
            '--broker-url',
            broker_url,
            '--state-file',
            str(state_file),
            *nice_option(nice),
            *args,
        ]
        super().__init__(None, command=command)
        if wait:
            self.wait_for_log(CONNECTED_LINE, START_TIMEOUT_SEC)


@dataclass(frozen=True)
class Received:
    topic: str
    payload: bytes
    retain: bool


class RawClient:
    """A bare MQTT 5 client: any account and client id, raw payloads (with the retain flag if
    asked), the broker's answer to each publication, and every message of `topics`."""

    def __init__(
        self,
        port: int,
        user: str,
        password: str,
        client_id: str = '',
        topics: Sequence[str] = (),
    ) -> None:
        self.received: list[Received] = []
        self.disconnections: list[str] = []
        """The reason of each disconnection (e.g. 'Session taken over')."""
        self._changed = threading.Condition()
        # key: message id, value: the broker's reason code for it
        self._acks: dict[int, ReasonCode] = {}
        self._ready = threading.Event()
        self._topics = topics
        self.connect_reason = ''
        self.mqtt = mqtt.Client(
            CallbackAPIVersion.VERSION2,
            client_id=client_id or f'raw_{uuid.uuid4().hex[:8]}',
            protocol=mqtt.MQTTv5,
        )
        self.mqtt.username_pw_set(user, password)
        self.mqtt.on_connect = self._on_connect
        self.mqtt.on_subscribe = lambda *_: self._ready.set()
        self.mqtt.on_message = self._on_message
        self.mqtt.on_publish = self._on_publish
        self.mqtt.on_disconnect = self._on_disconnect
        self.mqtt.connect('127.0.0.1', port)
        self.mqtt.loop_start()
        if not self._ready.wait(TIMEOUT_SEC):
            self.close()
            raise TimeoutError(f'{user}: no connection to the broker ({self.connect_reason})')

    def __enter__(self) -> 'RawClient':
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def close(self) -> None:
        self.mqtt.disconnect()
        self.mqtt.loop_stop()

    def publish(
        self, topic: str, payload: bytes | str, retain: bool = False, wait: bool = True
    ) -> str:
        """Publish at QoS 1 and wait for the broker's acknowledgement; its reason code (with
        `wait` False: '' at once)."""
        info = self.mqtt.publish(topic, payload, qos=1, retain=retain)
        if not wait:
            return ''
        with self._changed:
            if not self._changed.wait_for(lambda: info.mid in self._acks, TIMEOUT_SEC):
                raise TimeoutError(f'no acknowledgement of the publication to {topic}')
            return str(self._acks.pop(info.mid))

    def wait_for(self, condition: Callable[[list[Received]], Any], what: str) -> Any:
        """Wait until `condition(received)` is true; its value."""
        with self._changed:
            value = self._changed.wait_for(lambda: condition(self.received), TIMEOUT_SEC)
        if not value:
            raise TimeoutError(f'{what}: not within {TIMEOUT_SEC} s')
        return value

    def _on_connect(
        self, client: mqtt.Client, _: Any, __: Any, reason: ReasonCode, ___: Any
    ) -> None:
        self.connect_reason = str(reason)
        if reason.is_failure:
            return
        if self._topics:
            client.subscribe([(topic, 1) for topic in self._topics])
        else:
            self._ready.set()

    def _on_message(self, _: mqtt.Client, __: Any, message: mqtt.MQTTMessage) -> None:
        with self._changed:
            self.received.append(Received(message.topic, bytes(message.payload), message.retain))
            self._changed.notify_all()

    def _on_publish(self, _: mqtt.Client, __: Any, mid: int, reason: ReasonCode, ___: Any) -> None:
        with self._changed:
            self._acks[mid] = reason
            self._changed.notify_all()

    def _on_disconnect(
        self, _: mqtt.Client, __: Any, ___: Any, reason: ReasonCode, ____: Any
    ) -> None:
        with self._changed:
            self.disconnections.append(str(reason))
            self._changed.notify_all()


BROKER_START_TIMEOUT_SEC = 10.0


class BrokerProcess(MosquittoBroker):
    """A MosquittoBroker the tests and the bench start and stop themselves (`make fleet` runs
    its command under its own supervisor)."""

    process: NodeProcess | None = None

    def start(self) -> None:
        self.process = NodeProcess(None, command=self.command)
        self.process.wait_for_log(READY_LINE, BROKER_START_TIMEOUT_SEC)

    def stop(self) -> int:
        """SIGINT: mosquitto saves its sessions and queued messages, then exits."""
        if self.process is None:
            return 0
        process, self.process = self.process, None
        return process.stop()
