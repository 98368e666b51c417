"""Nothing the bridge sends is over the broker's message size limit, with a real Task Manager,
the bridge as users run it and a real mosquitto whose limit is small: the bridge learns it
from the broker and makes its documents fit (outgoing.py), so it never loses its connection
over a message of its own."""

import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check
from task_manager_mqtt.broker import CLOUD_USER
from task_manager_mqtt.fleet_client import FleetClient
from task_manager_mqtt.fleet_types import RobotView
from task_manager_mqtt.settings import DEFAULT_PREFIX
from task_manager_mqtt.testing import ROBOT, TESTER, BridgeProcess, BrokerProcess, RawClient
from task_manager_mqtt.topics import Topics

pytestmark = pytest.mark.ros
BROKER_MAX_BYTES = 65_536
"""The broker's limit: the bridge's own (1 MiB) is larger, the broker's CONNACK says less."""
RUNNING = 200
CONFIRM = {'prompt': 'load the tray', 'timeout_sec': 600}
"""Each task waits for an answer in the node (no server), until the stop cancels it."""
LONG_ID = 'x' * 240
"""With a number: 250 characters, one of the longest ids a task may have (256)."""


def split(robot: RobotView) -> int:
    """The robot's active tasks, once its document leaves some out (else -1), or 0 once none."""
    if not robot.active_tasks and not robot.active_tasks_omitted:
        return 0
    return (
        len(robot.active_tasks) + robot.active_tasks_omitted if robot.active_tasks_omitted else -1
    )


@pytest.fixture
def small_broker(tmp_path: Path) -> Iterator[BrokerProcess]:
    broker = BrokerProcess(
        tmp_path / 'broker',
        robots=[ROBOT],
        clouds=[CLOUD_USER, TESTER],
        max_payload_bytes=BROKER_MAX_BYTES,
    )
    broker.start()
    yield broker
    broker.stop()


def test_200_running_tasks_with_long_ids_fit_the_brokers_limit_and_stop_is_answered(
    robot: Robot, small_broker: BrokerProcess, tmp_path: Path
) -> None:
    active_topic = Topics(DEFAULT_PREFIX, ROBOT).active_tasks
    bridge = BridgeProcess(ROBOT, small_broker.url(ROBOT), tmp_path / 'acked')
    password = small_broker.passwords[TESTER]
    try:
        with (
            FleetClient(small_broker.url(), client_id='sizes-cloud') as fleet,
            RawClient(small_broker.port, TESTER, password, topics=[active_topic]) as raw,
        ):
            assert fleet.wait_online([ROBOT], TIMEOUT_SEC)
            tasks = [
                fleet.start_task(ROBOT, 'system/confirm', CONFIRM, task_id=f'{LONG_ID}{n:010d}')
                for n in range(RUNNING)
            ]
            assert all(task.accepted()['ok'] for task in tasks)
            assert fleet.wait_for(lambda robots: split(robots[ROBOT]) == RUNNING)
            stopped = fleet.stop(ROBOT)  # no reply before: the bridge was disconnected, again
            ends = [task.result()['status'] for task in tasks]
            assert fleet.wait_for(lambda robots: split(robots[ROBOT]) == 0)
            sizes = [len(message.payload) for message in raw.received]
            documents = [json.loads(message.payload) for message in raw.received]
    finally:
        bridge.stop()

    assert stopped['status'] == 'DONE' and set(ends) == {'CANCELED'}
    assert max(sizes) <= BROKER_MAX_BYTES
    largest = check(documents[sizes.index(max(sizes))], 'mqtt_active_tasks')
    assert largest['omitted'] > 0 and len(largest['tasks']) > 50
    assert {task['status'] for task in largest['tasks']} == {'IN_PROGRESS'}
    assert not [line for line in bridge.log_lines if 'lost the broker' in line]
    assert [line for line in bridge.log_lines if 'active_tasks of ' in line]  # said once
