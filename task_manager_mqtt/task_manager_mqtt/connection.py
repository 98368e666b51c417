"""The MQTT client of the bridge and of the FleetClient (paho-mqtt), made the same way."""

import socket
from typing import Any, overload

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

from task_manager_mqtt.settings import PACKET_HEADROOM_BYTES, Broker

RECONNECT_MIN_SEC = 1


def new_client(
    client_id: str,
    broker: Broker,
    reconnect_max_sec: int,
    max_in_flight: int,
    manual_ack: bool = False,
    client_class: type[mqtt.Client] = mqtt.Client,
) -> mqtt.Client:
    """An MQTT 5 client with the broker's credentials and TLS; it sends each packet at once.

    `max_in_flight`: QoS 1 messages sent before their acknowledgements (paho's default, 20,
    slows a burst). `manual_ack`: a message received is acknowledged by `client.ack()`, not
    as soon as it arrived. `client_class`: paho's Client, or a subclass of it.
    """
    client = client_class(
        CallbackAPIVersion.VERSION2,
        client_id=client_id,
        protocol=mqtt.MQTTv5,
        manual_ack=manual_ack,
    )
    if broker.username:
        client.username_pw_set(broker.username, broker.password or None)
    if broker.tls is not None:
        client.tls_set(
            ca_certs=broker.tls.ca_file or None,
            certfile=broker.tls.cert_file or None,
            keyfile=broker.tls.key_file or None,
        )
        if broker.tls.insecure:
            client.tls_insecure_set(True)
    client.reconnect_delay_set(RECONNECT_MIN_SEC, reconnect_max_sec)
    client.max_inflight_messages_set(max_in_flight)
    client.on_socket_open = _no_delay
    return client


def connect(
    client: mqtt.Client,
    broker: Broker,
    keepalive_sec: int,
    session_sec: int,
    receive_maximum: int = 0,
    start_loop: bool = True,
) -> None:
    """Connect in the background (retrying), keeping the session for `session_sec` when away;
    `receive_maximum`: the most QoS 1 messages not acknowledged yet that the broker may send
    (0: the broker's choice). `start_loop`: on paho's own thread (else the caller drives it)."""
    properties = Properties(PacketTypes.CONNECT)  # type: ignore[no-untyped-call]
    properties.SessionExpiryInterval = session_sec
    if receive_maximum:
        properties.ReceiveMaximum = receive_maximum
    client.connect_async(
        broker.host, broker.port, keepalive=keepalive_sec, clean_start=False, properties=properties
    )
    if start_loop:
        client.loop_start()


@overload
def largest_payload(connack: Properties | None, limit: int) -> int: ...
@overload
def largest_payload(connack: Properties | None, limit: None) -> int | None: ...
def largest_payload(connack: Properties | None, limit: int | None) -> int | None:
    """The largest payload to publish: `limit`, or less if the broker takes only smaller
    packets (MQTT 5's Maximum Packet Size, in its CONNACK). A larger packet would make the
    broker disconnect the client, and paho would send it again at each reconnection."""
    server = getattr(connack, 'MaximumPacketSize', None)
    if server is None:
        return limit
    server_limit = int(server) - PACKET_HEADROOM_BYTES
    return server_limit if limit is None else min(limit, server_limit)


def _no_delay(_: mqtt.Client, __: Any, sock: Any) -> None:
    """TCP_NODELAY: paho leaves Nagle's algorithm on, and a small packet written after
    another waited for the peer's delayed acknowledgement (40 ms)."""
    if isinstance(sock, socket.socket) or hasattr(sock, 'setsockopt'):
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
