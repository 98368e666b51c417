"""The console with real robots: the demo's Task Manager (a real process, over DDS) and its MQTT
bridge, on a real mosquitto; the console's Fleet in this process, on SQLite and PostgreSQL."""

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from task_manager_mqtt.testing import BridgeProcess, BrokerProcess

from task_manager.client import TaskManagerClient
from task_manager.testing.gateway import Robot
from task_manager_console.fleet import Fleet
from task_manager_console.robots import ConnectionState
from task_manager_console.simulation.robot import SimulatedRobot
from task_manager_console.simulation.robot_loop import TIMEOUT_SEC
from task_manager_console.store.fleet_history import HistoryFilter
from task_manager_console.testing import Results

pytestmark = pytest.mark.ros

ROBOT = 'robot1'
ONLINE_TIMEOUT_SEC = 30.0


@pytest.fixture
def start_bridge(broker: BrokerProcess, tmp_path: Path) -> Iterator[Callable[[], BridgeProcess]]:
    """Start robot1's bridge (`task-manager-mqtt`), connected; stopped at the end."""
    bridges: list[BridgeProcess] = []

    def start() -> BridgeProcess:
        bridge = BridgeProcess(ROBOT, broker.url(ROBOT), tmp_path / 'acked')
        bridges.append(bridge)
        return bridge

    yield start
    for bridge in bridges:
        bridge.stop()


def online(fleet: Fleet) -> bool:
    """Whether robot1 is ONLINE, reaching its Task Manager, and its tasks are declared."""
    return fleet.wait_for(
        lambda robots: ROBOT in robots and robots[ROBOT].online and robots[ROBOT].declares('fib'),
        ONLINE_TIMEOUT_SEC,
    )


def test_a_task_started_from_the_console_ends_and_is_stored_once(
    robot: Robot,
    start_bridge: Callable[[], BridgeProcess],
    start_console: Callable[..., Fleet],
) -> None:
    start_bridge()
    fleet = start_console()
    results = Results(fleet)
    assert online(fleet), fleet.robots
    state = fleet.robots[ROBOT]
    assert {t['task_name'] for t in state.tasks} >= {'fib', 'instant'}
    assert state.connection_state == ConnectionState.ONLINE and not state.silent

    reply = fleet.start_task(ROBOT, 'instant', {'data': True}, source='alice')
    assert reply['ok'] and reply['task_id']
    [stored] = results.wait(1)
    assert (stored['task_id'], stored['status'], stored['robot_id']) == (
        reply['task_id'],
        'DONE',
        ROBOT,
    )
    assert stored['source'] == 'CLOUD:alice'
    assert fleet.history.query(HistoryFilter(task_id=reply['task_id'])) == [stored]
    assert fleet.wait_for(lambda r: r[ROBOT].last_result == stored, TIMEOUT_SEC)


def test_a_robot_back_from_offline_has_its_backlog_stored_once_in_order(
    robot: Robot,
    start_bridge: Callable[[], BridgeProcess],
    start_console: Callable[..., Fleet],
) -> None:
    bridge = start_bridge()
    fleet = start_console()
    results = Results(fleet)
    assert online(fleet), fleet.robots
    first = fleet.start_task(ROBOT, 'instant', {'data': True})['task_id']
    results.wait(1)
    assert bridge.stop() == 0
    assert fleet.wait_for(lambda r: r[ROBOT].connection_state == 'OFFLINE', TIMEOUT_SEC)
    with TaskManagerClient('console_backlog_test', timeout_sec=TIMEOUT_SEC) as client:
        backlog = [client.run_task('instant', {'data': True}).task_id for _ in range(8)]
    start_bridge()
    stored = results.wait(9)
    assert [d['task_id'] for d in stored] == [first, *backlog]
    sequences = [d['sequence'] for d in stored]
    assert sequences == list(range(sequences[0], sequences[0] + 9))
    assert fleet.history.count(ROBOT) == 9
    assert fleet.duplicates == 0


def test_stop_all_shows_each_robots_answer(
    robot: Robot,
    start_bridge: Callable[[], BridgeProcess],
    start_console: Callable[..., Fleet],
    broker: BrokerProcess,
) -> None:
    start_bridge()
    fleet = start_console()
    away = SimulatedRobot(broker.port, 'robot2', broker.passwords['robot2'])
    away.connect()
    away.go_offline()
    assert online(fleet), fleet.robots
    assert fleet.wait_for(lambda r: 'robot2' in r and r['robot2'].since is not None, TIMEOUT_SEC)
    assert fleet.wait_for(lambda r: r['robot2'].connection_state == 'OFFLINE', TIMEOUT_SEC)

    answers = fleet.stop_all()
    assert list(answers) == [ROBOT, 'robot2']
    assert answers[ROBOT]['ok'] is True
    assert answers[ROBOT]['task']['task_name'] == 'system/stop'
    assert answers[ROBOT]['task']['status'] == 'DONE'
    assert answers['robot2']['ok'] is False
    assert answers['robot2']['error']['code'] == 'robot_offline'
