"""The simulated robots of the scale bench (simulation/): fifty on one thread of this process,
each on its own broker account, speak the bridge's protocol well enough that the console lists
every one as the bridge would show it and stores what each sends exactly once, in order."""

import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from task_manager_mqtt.testing import BrokerProcess

from task_manager_console.fleet import Fleet
from task_manager_console.simulation.documents import declared
from task_manager_console.simulation.robot import EVENTS_PER_TASK, SimulatedRobot, connect_all
from task_manager_console.simulation.robot_loop import TIMEOUT_SEC, RobotLoop
from task_manager_console.store.fleet_history import FleetHistory, HistoryFilter
from task_manager_console.testing import CONSOLE_USER

ROBOT_COUNT = 50
TASKS_EACH = 6


@pytest.fixture
def many_robots(tmp_path: Path) -> Iterator[tuple[BrokerProcess, list[SimulatedRobot]]]:
    """A mosquitto with fifty robot accounts and the console's, and fifty robots (not yet
    connected) on one loop; all stopped at the end."""
    robot_ids = [f'sim{number:02d}' for number in range(ROBOT_COUNT)]
    broker = BrokerProcess(tmp_path / 'broker', robot_ids, clouds=[CONSOLE_USER])
    broker.start()
    loop = RobotLoop()
    robots = [
        SimulatedRobot(broker.port, robot_id, broker.passwords[robot_id], loop=loop)
        for robot_id in robot_ids
    ]
    yield broker, robots
    for robot in robots:
        robot.close()
    loop.close()
    broker.stop()


def test_the_console_lists_and_stores_what_simulated_robots_send_exactly_once(
    many_robots: tuple[BrokerProcess, list[SimulatedRobot]], database_url: str
) -> None:
    broker, robots = many_robots
    robots[0].declared = [declared('dock', blocking=True, resources=['base', 'charger'])]
    threads_before = threading.active_count()
    connect_all(robots)
    assert threading.active_count() == threads_before  # fifty robots on their loop's thread
    history = FleetHistory.open(database_url)
    fleet = Fleet(broker.url(CONSOLE_USER), history)
    try:
        fleet.start(TIMEOUT_SEC)
        assert fleet.wait_for(
            lambda r: sum(s.online for s in r.values()) == ROBOT_COUNT, TIMEOUT_SEC
        )
        sent = robots[0].loop.run(
            lambda: [
                robot.next_event() for _ in range(TASKS_EACH * EVENTS_PER_TASK) for robot in robots
            ]
        )
        assert sum(sent) == ROBOT_COUNT * TASKS_EACH  # every third message a result
        stored_all: Callable[[], bool] = lambda: fleet.results_stored == sum(sent)  # noqa: E731
        assert fleet.wait_until(stored_all, TIMEOUT_SEC)
        again = robots[1].task(task_id='again')  # its 7th: sent twice, as after a reconnection
        robots[1].publish(robots[1].topics.result, again)
        robots[1].publish(robots[1].topics.result, again)
        assert fleet.wait_until(lambda: fleet.duplicates == 1, TIMEOUT_SEC)

        robots_now = fleet.robots
        docking = robots_now['sim00']
        assert docking.tasks == [robots[0].declared[0]]
        assert docking.tasks[0]['resources'] == ['base', 'charger']
        for robot in robots:
            state = robots_now[robot.robot_id]
            assert state.online and not state.silent and state.active == []
            assert state.last_result is not None
        for robot in robots[:3]:
            found = history.query(HistoryFilter(robot_id=robot.robot_id, limit=100))
            expected = list(range(1, TASKS_EACH + 1 + (robot is robots[1])))
            assert sorted(d['sequence'] for d in found) == expected  # each once
        assert history.count() == ROBOT_COUNT * TASKS_EACH + 1
        assert robots[0].refused == 0
    finally:
        fleet.close()
        history.close()
