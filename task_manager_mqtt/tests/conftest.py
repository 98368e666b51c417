"""Fixtures of the bridge's tests: a real mosquitto, a real Task Manager node, the bridge as
users run it, and the cloud's FleetClient."""

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from task_manager.testing.gateway import Robot
from task_manager.testing.process import TEST_NICENESS
from task_manager_mqtt.broker import CLOUD_USER
from task_manager_mqtt.fleet_client import FleetClient
from task_manager_mqtt.testing import ROBOT, TESTER, BridgeProcess, BrokerProcess

ONLINE_TIMEOUT_SEC = 20.0


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[BrokerProcess]:
    broker = BrokerProcess(
        tmp_path / 'broker', robots=[ROBOT, 'robot2'], clouds=[CLOUD_USER, TESTER]
    )
    broker.start()
    yield broker
    broker.stop()


@pytest.fixture
def start_bridge(broker: BrokerProcess, tmp_path: Path) -> Iterator[Callable[..., BridgeProcess]]:
    """Start `task-manager-mqtt` for robot1 (args added); stopped cleanly at the end, its
    output printed (pytest shows it when the test failed)."""
    bridges: list[BridgeProcess] = []

    def start(
        *args: str, wait: bool = True, url: str = '', nice: int | None = TEST_NICENESS
    ) -> BridgeProcess:
        bridge = BridgeProcess(
            ROBOT, url or broker.url(ROBOT), tmp_path / 'acked', *args, wait=wait, nice=nice
        )
        bridges.append(bridge)
        return bridge

    yield start
    for bridge in bridges:
        if not bridge.killed:
            bridge.stop()
        bridge.print_output()


@pytest.fixture
def fleet(broker: BrokerProcess) -> Iterator[FleetClient]:
    with FleetClient(broker.url(), client_id='test-cloud', events=True) as client:
        yield client


@pytest.fixture
def bridge(robot: Robot, start_bridge: Callable[..., BridgeProcess]) -> BridgeProcess:
    """The bridge of robot1, connected to the broker, its node running."""
    return start_bridge()


@pytest.fixture
def online(bridge: BridgeProcess, fleet: FleetClient) -> FleetClient:
    """The cloud client, once robot1 is ONLINE and reaches its node."""
    assert fleet.wait_online([ROBOT], ONLINE_TIMEOUT_SEC), fleet.robots
    return fleet
