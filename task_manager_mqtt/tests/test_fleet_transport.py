"""The FleetClient's transport (fleet/transport.py): messages read straight from their PUBLISH
packets, as mosquitto sends them (MQTT 5 properties among), a socket that reads ahead and
writes when flushed, and malformed packets that only ever raise ValueError."""

import json
import socket
import struct
import threading
from pathlib import Path
from typing import Any

from hypothesis import given
from hypothesis import strategies as st
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

from task_manager_mqtt.broker import CLOUD_USER
from task_manager_mqtt.fleet.transport import BufferedSocket, publish_parts
from task_manager_mqtt.fleet_client import FleetClient
from task_manager_mqtt.testing import ROBOT, TIMEOUT_SEC, BrokerProcess, RawClient
from task_manager_mqtt.topics import Topics

Document = dict[str, Any]


def test_messages_with_properties_are_read_as_mosquitto_sends_them(tmp_path: Path) -> None:
    broker = BrokerProcess(tmp_path / 'broker', robots=[ROBOT], clouds=[CLOUD_USER])
    broker.start()
    topics = Topics('task_manager/v1', ROBOT)
    results: list[Document] = []
    states: list[tuple[str, Document | None]] = []
    changed = threading.Condition()

    def on_result(_: str, task: Document) -> None:
        with changed:
            results.append(task)
            changed.notify_all()

    def on_state(_: str, name: str, document: Document | None) -> None:
        with changed:
            states.append((name, document))
            changed.notify_all()

    properties = Properties(PacketTypes.PUBLISH)  # type: ignore[no-untyped-call]
    properties.UserProperty = [('trace', 'x' * 300)]  # a properties length of two bytes
    properties.ContentType = 'application/json'
    properties.MessageExpiryInterval = 60
    try:
        with FleetClient(broker.url(), client_id='transport-test') as fleet:
            fleet.on_result(on_result)
            fleet.on_state(on_state)
            with RawClient(broker.port, ROBOT, broker.passwords[ROBOT], client_id=ROBOT) as robot:
                for sequence in (1, 2):
                    task = {'task_id': f't{sequence}', 'status': 'DONE', 'sequence': sequence}
                    info = robot.mqtt.publish(
                        topics.result, json.dumps(task), qos=sequence - 1, properties=properties
                    )
                    info.wait_for_publish(TIMEOUT_SEC)
                robot.publish(topics.active_tasks, b'{"tasks": [], "omitted": 2}', retain=True)
                with changed:
                    assert changed.wait_for(lambda: len(results) == 2 and states, TIMEOUT_SEC)
    finally:
        broker.stop()
    assert [task['task_id'] for task in results] == ['t1', 't2']  # QoS 0, then QoS 1
    assert states == [('active_tasks', {'tasks': [], 'omitted': 2})]


def publish_packet(topic: bytes, mid: int | None, properties: bytes, payload: bytes) -> bytes:
    """The variable header and payload of a PUBLISH packet (its properties given encoded)."""
    head = struct.pack('!H', len(topic)) + topic
    if mid is not None:
        head += struct.pack('!H', mid)
    length, encoded = len(properties), b''
    while True:
        byte, length = length & 0x7F, length >> 7
        encoded += bytes([byte | (0x80 if length else 0)])
        if not length:
            break
    return head + encoded + properties + payload


@given(
    topic=st.text(min_size=1, max_size=40),
    mid=st.integers(1, 65535),
    properties=st.binary(max_size=20_000),
    payload=st.binary(max_size=200),
)
def test_a_publish_packet_is_its_topic_id_and_payload(
    topic: str, mid: int, properties: bytes, payload: bytes
) -> None:
    encoded = topic.encode(errors='surrogatepass')
    try:
        encoded.decode()
    except UnicodeDecodeError:
        return  # no broker sends such a topic: see the malformed packets
    assert publish_parts(publish_packet(encoded, mid, properties, payload), 1) == (
        topic,
        payload,
        mid,
    )
    assert publish_parts(publish_packet(encoded, None, properties, payload), 0) == (
        topic,
        payload,
        0,
    )


@given(packet=st.binary(max_size=64), qos=st.sampled_from([0, 1]))
def test_a_malformed_publish_packet_only_raises_value_error(packet: bytes, qos: int) -> None:
    try:
        topic, payload, _ = publish_parts(packet, qos)
    except (ValueError, struct.error):
        return
    assert topic and len(payload) <= len(packet)


def test_a_topic_alias_or_bad_utf_8_goes_paho_s_way() -> None:
    for packet in (
        publish_packet(b'', 1, b'\x23\x00\x01', b'{}'),  # Topic Alias 1, no topic name
        publish_packet(b'robot\xff', 1, b'', b'{}'),
        publish_packet(b'robot1/result', 1, b'\x26', b'')[:-1],  # properties past the end
    ):
        try:
            publish_parts(packet, 1)
        except ValueError:
            continue
        raise AssertionError(f'{packet!r} was read')


def test_the_socket_reads_ahead_and_writes_when_flushed() -> None:
    near, far = socket.socketpair()
    near.setblocking(False)
    buffered = BufferedSocket(near)
    far.sendall(b'\x30\x05hello\x40\x02\x00\x01')
    assert buffered.recv(1) == b'\x30'  # one read took it all
    assert buffered.pending() == 10
    assert buffered.recv(1) + buffered.recv(5) == b'\x05hello'
    assert buffered.recv(4) == b'\x40\x02\x00\x01' and buffered.pending() == 0

    chunk = b'x' * 65536
    written = 0
    while written < 8 * len(chunk):
        written += buffered.send(chunk)  # kept, not written
    assert buffered.holds_writes
    buffered.flush()  # as much as the socket takes now
    received = b''
    far.settimeout(TIMEOUT_SEC)
    while len(received) < written:
        received += far.recv(1 << 20)
        buffered.flush()
    assert received == b'x' * written and not buffered.holds_writes
    buffered.close()
    assert far.recv(10) == b''
    far.close()
