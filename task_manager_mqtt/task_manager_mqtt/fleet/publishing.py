"""`RequestPublisher`: the FleetClient's requests to robots, each published once, and the
broker's acknowledgement of each: a request the broker refuses (too large for it, not
allowed) fails its reply at once rather than waiting out its timeout."""

import threading
from concurrent.futures import Future
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.reasoncodes import ReasonCode

from task_manager.protocol.errors import RefusalCode
from task_manager_mqtt.fleet.receiving import FleetReceiver
from task_manager_mqtt.fleet_types import Document, FleetError


class RequestPublisher:
    """Publishes requests (QoS 1) and fails the reply of one the broker refuses."""

    def __init__(self, client: mqtt.Client, receiver: FleetReceiver) -> None:
        self._mqtt = client
        self._receiver = receiver
        self._lock = threading.Lock()
        # key: message id of a request not acknowledged yet, value: its request id
        self._unacknowledged: dict[int, str] = {}
        # key: message id, value: the broker's answer, come before publish() returned
        self._early_acks: dict[int, ReasonCode] = {}
        self.largest_payload: int | None = None
        """The largest request the broker takes (MQTT 5's Maximum Packet Size); None: any."""

    def publish(self, topic: str, request_id: str, payload: bytes, reply: Future[Document]) -> None:
        """Send a request whose reply the receiver hands to `reply`; one larger than the
        broker takes is never sent (its reply fails `payload_too_large`)."""
        limit = self.largest_payload
        if limit is not None and len(payload) > limit:
            message = f'the request is {len(payload)} bytes; the broker takes at most {limit}'
            reply.set_exception(FleetError(message, RefusalCode.PAYLOAD_TOO_LARGE))
            return
        self._receiver.expect_reply(request_id, reply)
        # not under self._lock: paho calls on_publish holding a lock publish() takes too
        info = self._mqtt.publish(topic, payload, qos=1)
        with self._lock:
            early = self._early_acks.pop(info.mid, None)
            if early is None:
                self._unacknowledged[info.mid] = request_id
        if early is not None:
            self._refused(request_id, early)

    def on_publish(self, _: mqtt.Client, __: Any, mid: int, reason: ReasonCode, ___: Any) -> None:
        """paho's on_publish: the broker's answer to one of our messages."""
        with self._lock:
            request_id = self._unacknowledged.pop(mid, None)
            if request_id is None:  # publish() has not returned its id yet
                self._early_acks[mid] = reason
                return
        self._refused(request_id, reason)

    def _refused(self, request_id: str, reason: ReasonCode) -> None:
        if not reason.is_failure:
            return
        reply = self._receiver.take_reply(request_id)
        if reply is not None and not reply.done():
            message = f'the broker refused the request: {reason} (too large for it, or not allowed)'
            reply.set_exception(FleetError(message, RefusalCode.REFUSED_BY_BROKER))
