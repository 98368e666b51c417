""" "Any robot": the choice among robots' states, and why each other one was not chosen."""

from datetime import UTC, datetime
from typing import Any

from task_manager_console.choosing import choose_robot
from task_manager_console.robots import ConnectionState, RobotState


def robot(
    robot_id: str, state: str = 'ONLINE', active: int = 0, status: str = 'IN_PROGRESS'
) -> RobotState:
    """A robot declaring `drive` (blocking) and `photo`, running `active` drives."""
    running = [
        {'task_id': f'{robot_id}-{n}', 'task_name': 'drive', 'status': status}
        for n in range(active)
    ]
    return RobotState(
        robot_id,
        connection_state=ConnectionState(state),
        since=datetime(2026, 1, 1, tzinfo=UTC),
        task_manager_connected=state == 'ONLINE',
        tasks=[{'task_name': 'drive', 'blocking': True}, {'task_name': 'photo'}],
        active=running,
    )


def test_one_busy_one_offline_one_free_chooses_the_free_one() -> None:
    fleet = [robot('busy', active=1), robot('away', state='OFFLINE'), robot('free')]
    choice = choose_robot('drive', fleet)
    assert choice.robot_id == 'free'
    assert 'free is ONLINE, declares drive' in choice.reason
    assert choice.others == {
        'away': 'OFFLINE',
        'busy': 'its resources for drive are busy',
    }


def test_the_least_loaded_then_the_first_by_id() -> None:
    photo = [robot('b'), robot('a'), robot('c', active=2, status='QUEUED')]
    choice = choose_robot('photo', photo)
    assert choice.robot_id == 'a'
    assert choice.others['b'] == 'as able as a, which comes first by id'
    assert choice.others['c'].startswith('busier: 2 active tasks')


def test_only_the_requested_robots_and_none_when_none_can() -> None:
    fleet = [robot('a'), robot('b', state='CONNECTIONBROKEN')]
    choice = choose_robot('photo', fleet, requested=['b', 'z'])
    assert choice.robot_id is None
    assert choice.reason == 'no ONLINE robot declares photo'
    assert choice.others == {'z': 'no such robot on the broker', 'b': 'CONNECTIONBROKEN'}
    assert choose_robot('dance', fleet).others['a'] == 'does not declare dance'


def test_the_declared_resources_are_those_the_robots_task_manager_would_say() -> None:
    """`dock` and `drive` share `base`; `scan` is blocking and `photo` holds the camera: a robot
    docking has `base` busy, one scanning (blocking) has the camera free."""
    tasks: list[dict[str, Any]] = [
        {'task_name': 'drive', 'resources': ['base']},
        {'task_name': 'dock', 'resources': ['base', 'charger']},
        {'task_name': 'scan', 'blocking': True, 'reentrant': True},
        {'task_name': 'photo', 'resources': ['camera'], 'reentrant': True},
    ]

    def running(robot_id: str, task_name: str) -> RobotState:
        task = {'task_id': f'{robot_id}-1', 'task_name': task_name, 'status': 'IN_PROGRESS'}
        return RobotState(
            robot_id,
            connection_state=ConnectionState.ONLINE,
            task_manager_connected=True,
            tasks=tasks,
            active=[task],
        )

    docking, scanning = running('a-docking', 'dock'), running('b-scanning', 'scan')
    drive = choose_robot('drive', [docking, scanning])
    photo = choose_robot('photo', [docking, scanning])
    assert drive.robot_id == 'b-scanning'
    assert drive.others == {'a-docking': 'its resources for drive are busy'}
    assert photo.robot_id == 'a-docking'  # both free, one active task each: the first by id
    assert photo.others == {'b-scanning': 'as able as a-docking, which comes first by id'}
