"""The vehicle's MQTT connection: its last will, ONLINE and OFFLINE, what it subscribes to,
and every publication with its header, QoS and retain flag (paho-mqtt, made as the MQTT
bridge makes its client).

No message larger than the broker takes is ever sent: the broker would disconnect the vehicle
for it, at each attempt. The adapter shortens state to fit (fitting.py); any other message
too large is not sent, and said so in the log.
"""

import json
import logging
import threading
from collections.abc import Callable
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.reasoncodes import ReasonCode
from task_manager_mqtt.connection import connect, largest_payload, new_client
from task_manager_mqtt.settings import Broker

from task_manager.core.bounds import TASK_DATA_MAX_BYTES
from task_manager_vda5050.topics import DELIVERY, INBOUND, Headers, Vehicle

LOG = logging.getLogger('task_manager_vda5050')
MAX_IN_FLIGHT = 20
SESSION_SEC = 0
"""No session kept while away: the inbound topics are QoS 0, nothing would be queued."""


def _ignore(*_: object) -> None:
    pass


class Link:
    """`on_message(topic name, payload)` and `on_connected()` (once subscribed and ONLINE
    sent) run on paho's thread: set them before `start()`."""

    def __init__(
        self, vehicle: Vehicle, broker: Broker, keepalive_sec: int = 10, reconnect_max_sec: int = 2
    ) -> None:
        self.vehicle = vehicle
        self.headers = Headers(vehicle)
        self._lock = threading.Lock()
        self.on_message: Callable[[str, bytes], None] = _ignore
        self.on_connected: Callable[[], None] = _ignore
        self._broker = broker
        self._keepalive_sec = keepalive_sec
        self.refused = threading.Event()
        """Set when the broker refuses the credentials (no retrying helps)."""
        self.largest_payload = TASK_DATA_MAX_BYTES
        """The largest message to send: less when the broker's CONNACK says it takes less."""
        self._too_large: set[str] = set()
        """The topics whose last message was too large to send (said once in the log)."""
        self._stopping = False
        client_id = broker.username or f'{vehicle.manufacturer}_{vehicle.serial_number}'
        self.mqtt = new_client(client_id, broker, reconnect_max_sec, MAX_IN_FLIGHT)
        self.mqtt.will_set(
            vehicle.topic('connection'),
            json.dumps(self._with_header('connection', {'connectionState': 'CONNECTIONBROKEN'})),
            qos=1,
            retain=True,
        )
        self.mqtt.on_connect = self._connected
        self.mqtt.on_message = self._message
        self.mqtt.on_subscribe = self._subscribed
        self.mqtt.on_disconnect = self._disconnected

    def start(self) -> None:
        connect(self.mqtt, self._broker, self._keepalive_sec, SESSION_SEC)

    @property
    def connected(self) -> bool:
        return self.mqtt.is_connected()

    def room(self) -> int:
        """The most bytes the fields of a message may take (as JSON) for it to be sent."""
        return self.largest_payload - self.headers.largest_size()

    def publish(self, topic: str, fields: dict[str, Any]) -> dict[str, Any] | None:
        """Send `fields` with a header on `topic` (headerId counted even when offline, as the
        standard says); the message sent, or None when it is larger than the broker takes."""
        qos, retain = DELIVERY[topic]
        with self._lock:
            message = self._with_header(topic, fields)
            payload = json.dumps(message)
            if len(payload) > self.largest_payload:
                if topic not in self._too_large:
                    LOG.error(
                        'a %s message of %d bytes not sent: the broker takes at most %d '
                        '(said once, until one fits)',
                        topic,
                        len(payload),
                        self.largest_payload,
                    )
                self._too_large.add(topic)
                return None
            self._too_large.discard(topic)
            self.mqtt.publish(self.vehicle.topic(topic), payload, qos, retain)
        return message

    def stop(self, timeout_sec: float = 5.0) -> None:
        """OFFLINE (retained), delivered before a clean disconnection (no last will)."""
        self._stopping = True
        if self.connected:
            info = self.mqtt.publish(
                self.vehicle.topic('connection'),
                json.dumps(self._with_header('connection', {'connectionState': 'OFFLINE'})),
                qos=1,
                retain=True,
            )
            try:
                info.wait_for_publish(timeout_sec)
            except RuntimeError as error:  # the connection was lost meanwhile: the will says it
                LOG.warning('OFFLINE not sent: %s', error)
        self.mqtt.disconnect()
        self.mqtt.loop_stop()

    def _with_header(self, topic: str, fields: dict[str, Any]) -> dict[str, Any]:
        return {**self.headers.header(topic), **fields}

    def _connected(
        self, client: mqtt.Client, _: Any, __: Any, reason: ReasonCode, properties: Any
    ) -> None:
        if reason.is_failure:
            LOG.error('the broker refused the connection: %s', reason)
            if reason.getName() in ('Bad user name or password', 'Not authorized'):
                self.refused.set()
            return
        self.largest_payload = largest_payload(properties, TASK_DATA_MAX_BYTES)
        client.subscribe([(self.vehicle.topic(name), DELIVERY[name][0]) for name in INBOUND])

    def _subscribed(self, _: mqtt.Client, __: Any, ___: int, reasons: Any, ____: Any) -> None:
        """ONLINE once the vehicle hears its order and instantActions topics."""
        self.publish('connection', {'connectionState': 'ONLINE'})
        LOG.info('connected to the broker %s as %s', self._broker.url, self.vehicle.prefix)
        self.on_connected()

    def _disconnected(
        self, _: mqtt.Client, __: Any, ___: Any, reason: ReasonCode, ____: Any
    ) -> None:
        if self._stopping:
            LOG.info('disconnected from the broker')
        else:
            LOG.warning('disconnected from the broker (%s); reconnecting', reason)

    def _message(self, _: mqtt.Client, __: Any, message: mqtt.MQTTMessage) -> None:
        name = message.topic.rsplit('/', 1)[-1]
        if message.topic == self.vehicle.topic(name) and name in INBOUND:
            self.on_message(name, bytes(message.payload))
