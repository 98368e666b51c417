"""The bridge's connection: retained state, last will, credentials, ACL, a broker not there."""

import json
import threading
from collections.abc import Callable
from pathlib import Path

import paho.mqtt.client as mqtt
import pytest
from paho.mqtt.enums import CallbackAPIVersion

from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check
from task_manager_mqtt.broker import MosquittoBroker
from task_manager_mqtt.fleet_client import FleetClient, RobotView
from task_manager_mqtt.testing import ROBOT, BridgeProcess

pytestmark = pytest.mark.ros
KEEPALIVE_SEC = 1
RETRIES_SEC = 1.5
"""Long enough for the bridge's first two attempts (at 0 and 1 s)."""


def state_of(fleet: FleetClient) -> str:
    robot = fleet.robots.get(ROBOT)
    return str(robot.connection['connection_state']) if robot and robot.connection else ''


def wait_state(fleet: FleetClient, state: str) -> None:
    assert fleet.wait_for(lambda _: state_of(fleet) == state, TIMEOUT_SEC), state_of(fleet)


def test_retained_state_last_will_and_clean_stop(
    robot: Robot, start_bridge: Callable[..., BridgeProcess], broker: MosquittoBroker
) -> None:
    bridge = start_bridge('--keepalive-sec', str(KEEPALIVE_SEC))
    with FleetClient(broker.url()) as fleet:  # joins later: gets the retained state
        assert fleet.wait_online([ROBOT], TIMEOUT_SEC)
        view: RobotView = fleet.robots[ROBOT]
        check(view.connection, 'mqtt_connection')
        assert {t['task_name'] for t in view.tasks} >= {'fib', 'instant'}
        fib = fleet.start_task(ROBOT, 'fib', {'order': 1})
        assert fleet.wait_for(
            lambda r: [t['task_id'] for t in r[ROBOT].active_tasks] == [fib.task_id]
        )

        bridge.kill()  # no clean stop: the broker sends the last will
        wait_state(fleet, 'CONNECTIONBROKEN')
        assert view.connection is not None and not view.connection['task_manager_connected']

        bridge = start_bridge()
        wait_state(fleet, 'ONLINE')
        assert bridge.stop() == 0
        wait_state(fleet, 'OFFLINE')
        check(view.connection, 'mqtt_connection')


def test_a_robot_writes_only_under_its_own_id(broker: MosquittoBroker, fleet: FleetClient) -> None:
    seen: list[str] = []
    fleet.on_result(lambda robot_id, _: seen.append(robot_id))
    published = threading.Event()
    robot = mqtt.Client(CallbackAPIVersion.VERSION2, client_id='acl_test', protocol=mqtt.MQTTv5)
    robot.username_pw_set(ROBOT, broker.passwords[ROBOT])
    robot.on_connect = lambda *_: published.set()
    robot.connect('127.0.0.1', broker.port)
    robot.loop_start()
    try:
        assert published.wait(TIMEOUT_SEC)
        document = json.dumps({'task_id': 'forged', 'sequence': 1})
        robot.publish('task_manager/v1/robot2/result', document, qos=1).wait_for_publish(
            TIMEOUT_SEC
        )
        robot.publish(f'task_manager/v1/{ROBOT}/result', document, qos=1).wait_for_publish(
            TIMEOUT_SEC
        )
        assert fleet.wait_for(lambda _: bool(seen), TIMEOUT_SEC)
    finally:
        robot.disconnect()
        robot.loop_stop()
    assert seen == [ROBOT]  # the message under robot2's id was dropped by the broker


def test_wrong_credentials_exit_2_with_one_line(
    broker: MosquittoBroker, start_bridge: Callable[..., BridgeProcess]
) -> None:
    bridge = start_bridge(url=f'mqtt://{ROBOT}:wrong@127.0.0.1:{broker.port}', wait=False)
    assert bridge.wait_exit(TIMEOUT_SEC) == 2
    refused = [line for line in bridge.log_lines if 'refused the credentials' in line]
    assert len(refused) == 1, bridge.log_lines


def test_a_broker_down_at_start_is_retried_and_said_once(
    tmp_path: Path, start_bridge: Callable[..., BridgeProcess]
) -> None:
    later = MosquittoBroker(tmp_path / 'later', robots=[ROBOT])
    bridge = start_bridge(url=later.url(ROBOT), wait=False)
    bridge.wait_for_log('cannot reach the broker', TIMEOUT_SEC)
    threading.Event().wait(RETRIES_SEC)  # time for more attempts, which must not be logged
    later.start()
    try:
        bridge.wait_for_log('connected to the broker', 2 * TIMEOUT_SEC)
        assert sum('cannot reach the broker' in line for line in bridge.log_lines) == 1
    finally:
        bridge.stop()
        later.stop()


def test_tls_with_the_brokers_own_certificate_authority(
    robot: Robot, start_bridge: Callable[..., BridgeProcess], tmp_path: Path
) -> None:
    secure = MosquittoBroker(tmp_path / 'tls', robots=[ROBOT], tls=True)
    secure.start()
    try:
        assert secure.url().startswith('mqtts://') and secure.ca_file is not None
        bridge = start_bridge('--ca-file', str(secure.ca_file), url=secure.url(ROBOT))
        with FleetClient(secure.url(), ca_file=str(secure.ca_file)) as fleet:
            assert fleet.wait_online([ROBOT], TIMEOUT_SEC)
            task = fleet.start_task(ROBOT, 'instant', {'data': True})
            assert task.result()['status'] == 'DONE'
        assert bridge.stop() == 0
    finally:
        secure.stop()
