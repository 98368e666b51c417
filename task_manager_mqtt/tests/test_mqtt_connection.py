"""The bridge's connection: retained state, last will, credentials, ACL, a broker not there."""

import json
import os
import threading
from collections.abc import Callable
from pathlib import Path

import pytest

from task_manager.cpu_priority import GATEWAY_NICENESS
from task_manager.process_setup import EXIT_NODE_UNHEARD
from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check
from task_manager.testing.process import held_up_with_its_node, thread_nice_values
from task_manager_mqtt.fleet_client import FleetClient
from task_manager_mqtt.fleet_types import RobotView
from task_manager_mqtt.settings import DEFAULT_PREFIX as PREFIX
from task_manager_mqtt.testing import ROBOT, TESTER, BridgeProcess, BrokerProcess, RawClient
from task_manager_mqtt.topics import Topics

pytestmark = pytest.mark.ros
KEEPALIVE_SEC = 1
NOT_AUTHORIZED = 'Not authorized'
"""The reason code of the broker's acknowledgement of a publication its ACL refused."""
STOP = json.dumps({'request_id': 'acl-test', 'op': 'stop'})
RETRIES_SEC = 1.5
"""Long enough for the bridge's first two attempts (at 0 and 1 s)."""


def state_of(fleet: FleetClient) -> str:
    robot = fleet.robots.get(ROBOT)
    return str(robot.connection['connection_state']) if robot and robot.connection else ''


def wait_state(fleet: FleetClient, state: str) -> None:
    assert fleet.wait_for(lambda _: state_of(fleet) == state, TIMEOUT_SEC), state_of(fleet)


def test_retained_state_last_will_and_clean_stop(
    robot: Robot, start_bridge: Callable[..., BridgeProcess], broker: BrokerProcess
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


def test_a_robot_writes_only_its_own_outgoing_topics(
    broker: BrokerProcess, fleet: FleetClient
) -> None:
    seen: list[str] = []
    fleet.on_result(lambda robot_id, _: seen.append(robot_id))
    document = json.dumps({'task_id': 'forged', 'sequence': 1})
    own, other = Topics(PREFIX, ROBOT), Topics(PREFIX, 'robot2')
    with RawClient(broker.port, ROBOT, broker.passwords[ROBOT]) as robot:
        assert robot.publish(other.result, document) == NOT_AUTHORIZED
        assert robot.publish(own.request, STOP) == NOT_AUTHORIZED  # no requests to itself
        assert robot.publish(own.result, document) == 'Success'
    with RawClient(broker.port, TESTER, broker.passwords[TESTER]) as cloud:
        assert cloud.publish(own.result, document) == NOT_AUTHORIZED  # no result as a robot
        assert cloud.publish(Topics(PREFIX, TESTER).result, document) == NOT_AUTHORIZED
        assert cloud.publish(own.request, STOP) == 'No matching subscribers'  # accepted
    assert fleet.wait_for(lambda _: bool(seen), TIMEOUT_SEC)
    assert seen == [ROBOT]  # the others were dropped by the broker


def test_another_account_cannot_take_over_a_bridges_connection(
    broker: BrokerProcess, start_bridge: Callable[..., BridgeProcess], fleet: FleetClient
) -> None:
    bridge = start_bridge()
    wait_state(fleet, 'ONLINE')  # (published once it has subscribed to its requests)
    for client_id in (f'task_manager_{ROBOT}', ROBOT):  # the bridge's id, and its user name
        with RawClient(broker.port, 'robot2', broker.passwords['robot2'], client_id) as thief:
            assert thief.connect_reason == 'Success'
    # a reply after: had the bridge been disconnected, it would have said so before (its log)
    assert fleet.request(ROBOT, 'dance').result(TIMEOUT_SEC)['error']['field'] == 'op'
    assert bridge.stop() == 0
    assert not [line for line in bridge.log_lines if 'lost the broker' in line], bridge.log_lines
    assert sum('connected to the broker' in line for line in bridge.log_lines) == 1


def test_the_bridge_runs_nicer_than_the_robot(
    robot: Robot, start_bridge: Callable[..., BridgeProcess]
) -> None:
    bridge = start_bridge(nice=None)  # as users start it; connected to the broker and the node
    own = os.getpriority(os.PRIO_PROCESS, 0)
    assert thread_nice_values(bridge.process.pid) == {max(own, GATEWAY_NICENESS)}


def test_wrong_credentials_exit_2_with_one_line(
    broker: BrokerProcess, start_bridge: Callable[..., BridgeProcess]
) -> None:
    bridge = start_bridge(url=f'mqtt://{ROBOT}:wrong@127.0.0.1:{broker.port}', wait=False)
    assert bridge.wait_exit(TIMEOUT_SEC) == 2
    refused = [line for line in bridge.log_lines if 'refused the credentials' in line]
    assert len(refused) == 1, bridge.log_lines


def test_a_broker_down_at_start_is_retried_and_said_once(
    tmp_path: Path, start_bridge: Callable[..., BridgeProcess]
) -> None:
    later = BrokerProcess(tmp_path / 'later', robots=[ROBOT])
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
    secure = BrokerProcess(tmp_path / 'tls', robots=[ROBOT], tls=True)
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


def test_a_bridge_held_up_that_no_longer_hears_its_node_exits_3(
    robot: Robot, bridge: BridgeProcess, online: FleetClient
) -> None:
    """Stopped (SIGSTOP) with its node for longer than its client's check takes for a hold-up,
    then let go while the node stays stopped: it hears nothing, says so, publishes OFFLINE and
    exits 3, for its supervisor to start a new process (one that hears the node)."""
    assert held_up_with_its_node(bridge, robot.process, TIMEOUT_SEC) == EXIT_NODE_UNHEARD
    bridge.wait_for_log('has not heard the Task Manager again within 10 s', TIMEOUT_SEC)
    wait_state(online, 'OFFLINE')
