"""The console's doors with real robots (issue 38, item 3): Task Managers (real processes, over
DDS) and their MQTT bridges on a real mosquitto, `task-manager-console` as users run it. What
is started, cancelled, paused, resumed, reprioritized, confirmed and stopped through the REST API
reaches the robot and comes back as its answer, its result stored and streamed; "any robot"
with one robot busy, one offline and one free chooses the free one and says why."""

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, cast

import httpx
import pytest
from task_manager_mqtt.testing import BridgeProcess, BrokerProcess
from task_manager_web.doors_testing import ADMIN, VIEWER

from task_manager.testing.gateway import Robot
from task_manager_console.doors_testing import OPERATOR, ConsoleProcess, EventReader, wait_for
from task_manager_console.simulation.robot import SimulatedRobot

pytestmark = pytest.mark.ros

ROBOT = 'robot1'
START_TIMEOUT_SEC = 30.0
NAVIGATE = 'navigation/navigate_to_pose'
FIB = {'task_name': 'fib', 'task_data': {'order': 1}}
Document = dict[str, Any]


@pytest.fixture
def bridge(robot: Robot, broker: BrokerProcess, tmp_path: Path) -> Iterator[BridgeProcess]:
    """robot1's bridge, to the Task Manager of the `robot` fixture (this test's ROS domain)."""
    bridge = BridgeProcess(ROBOT, broker.url(ROBOT), tmp_path / 'acked')
    yield bridge
    bridge.stop()


def robot_state(http: httpx.Client, robot_id: str) -> Document:
    response = http.get(f'/api/robots/{robot_id}')
    return response.json() if response.status_code == 200 else {}


def online(http: httpx.Client, robot_id: str, task_name: str) -> Document:
    """Wait until the console sees the robot ONLINE, reaching its Task Manager and declaring
    `task_name`; its state."""
    state: Document = wait_for(
        lambda: robot_state(http, robot_id),
        lambda r: (
            r.get('task_manager_connected')
            and r['connection_state'] == 'ONLINE'
            and any(t['task_name'] == task_name for t in r['tasks'])
        ),
        f'{robot_id} ONLINE with {task_name}',
    )
    return state


def active(http: httpx.Client, robot_id: str, task_id: str, status: str) -> Document:
    """Wait until the robot's active tasks, as the console shows them, have `task_id` in
    `status`; the task."""
    state = wait_for(
        lambda: robot_state(http, robot_id),
        lambda r: any(t['task_id'] == task_id and t['status'] == status for t in r['active']),
        f'{task_id} {status} on {robot_id}',
    )
    return next(t for t in state['active'] if t['task_id'] == task_id)


def stored(http: httpx.Client, task_id: str) -> Document:
    """Wait until the fleet history has the task's result; it."""
    found = wait_for(
        lambda: http.get('/api/history', params={'task_id': task_id}).json(), len, task_id
    )
    return cast(Document, found[0])


def test_a_task_started_through_the_doors_is_stored_and_streamed_as_its_starter_s(
    robot: Robot, bridge: BridgeProcess, console: ConsoleProcess
) -> None:
    with console.client(OPERATOR) as alice, console.client(VIEWER) as viewer:
        online(viewer, ROBOT, 'instant')
        events = EventReader(console)
        try:
            started = alice.post(
                f'/api/robots/{ROBOT}/tasks/start',
                json={'task_name': 'instant', 'task_data': {'data': True}, 'task_id': 'by-alice'},
            )
            [result] = events.wait(
                lambda e: [d for k, d in e if k == 'result' and d['task_id'] == 'by-alice'],
                'its result streamed',
            )
        finally:
            events.close()
        mission = alice.post(
            f'/api/robots/{ROBOT}/missions',
            json={'subtasks': [{'task_name': 'instant', 'task_data': {'data': True}}] * 2},
        )
        again = alice.post(
            f'/api/robots/{ROBOT}/tasks/start',
            json={'task_name': 'instant', 'task_data': {'data': True}, 'task_id': 'by-alice'},
        )
        refused = viewer.post(f'/api/robots/{ROBOT}/tasks/start', json={'task_name': 'fib'})
        history = viewer.get('/api/history', params={'source': 'CLOUD:alice', 'robot_id': ROBOT})
        mission_end = stored(viewer, mission.json()['task_id'])

    assert started.status_code == 202, started.text
    assert started.json()['robot_id'] == ROBOT
    assert (started.json()['task_id'], started.json()['duplicate']) == ('by-alice', False)
    assert (result['robot_id'], result['status'], result['source']) == (
        ROBOT,
        'DONE',
        'CLOUD:alice',
    )
    assert [t['task_id'] for t in history.json()][-1] == 'by-alice'
    assert mission.status_code == 202, mission.text
    assert len(mission.json()['subtask_ids']) == 2
    assert (mission_end['task_name'], mission_end['status']) == ('system/mission', 'DONE')
    assert again.status_code == 202 and again.json()['duplicate'] is True
    assert refused.status_code == 403
    assert not robot.fib.goals.items  # nothing of the viewer's request reached the robot


def test_cancel_pause_resume_reprioritize_confirm_and_stop_come_back_as_the_robots_answers(
    robot: Robot, bridge: BridgeProcess, console: ConsoleProcess, broker: BrokerProcess
) -> None:
    away = SimulatedRobot(broker.port, 'robot2', broker.passwords['robot2'])
    away.connect()
    away.go_offline()
    url = f'/api/robots/{ROBOT}'
    with console.client(OPERATOR) as alice, console.client(ADMIN) as admin:
        online(alice, ROBOT, 'fib')
        long = alice.post(f'{url}/tasks/start', json={**FIB, 'task_id': 'long'})
        assert long.status_code == 202, long.text
        robot.fib.wait_for_goals(1, START_TIMEOUT_SEC)
        active(alice, ROBOT, 'long', 'IN_PROGRESS')
        paused = alice.post(f'{url}/tasks/pause', json={'task_ids': ['long']})
        resumed = alice.post(f'{url}/tasks/resume', json={'task_ids': ['long']})
        by_operator = alice.post(
            f'{url}/tasks/reprioritize', json={'task_ids': ['long'], 'priority': 7}
        )
        by_admin = admin.post(
            f'{url}/tasks/reprioritize', json={'task_ids': ['long'], 'priority': 7}
        )
        wait = {'task_name': 'system/confirm', 'task_data': {'prompt': 'load'}, 'task_id': 'tray'}
        assert alice.post(f'{url}/tasks/start', json=wait).status_code == 202
        active(alice, ROBOT, 'tray', 'IN_PROGRESS')
        not_waiting = alice.post(f'{url}/tasks/long/confirm', json={})
        unknown = alice.post(f'{url}/tasks/nothing/confirm', json={})
        confirmed = alice.post(f'{url}/tasks/tray/confirm', json={'comment': 'loaded'})
        cancelled = alice.post(f'{url}/tasks/cancel', json={'task_ids': ['long']})
        long_end = stored(alice, 'long')
        stopped = alice.post(f'{url}/stop')
        wait_for(
            lambda: alice.get('/api/robots/robot2').json(),
            lambda r: r.get('connection_state') == 'OFFLINE',
            'robot2 OFFLINE',
        )
        stop_all = alice.post('/api/fleet/stop')

    assert paused.status_code == 200, paused.text
    assert paused.json()['paused'] == [] and len(paused.json()['errors']) == 1  # pause: none
    assert resumed.status_code == 200 and resumed.json()['resumed'] == []
    assert by_operator.status_code == 403
    assert by_admin.status_code == 200, by_admin.text
    assert (by_admin.json()['task_name'], by_admin.json()['status']) == (
        'system/reprioritize',
        'DONE',
    )
    assert (not_waiting.status_code, not_waiting.json()['error']['code']) == (409, 'not_waiting')
    assert (unknown.status_code, unknown.json()['error']['code']) == (404, 'unknown_task_id')
    assert confirmed.status_code == 200, confirmed.text
    assert (confirmed.json()['outcome'], confirmed.json()['comment']) == ('confirmed', 'loaded')
    assert confirmed.json()['by'] == 'CLOUD:alice'  # the token's name, as the web gateway's
    assert cancelled.status_code == 200, cancelled.text
    assert cancelled.json()['task_name'] == 'system/cancel_task'
    assert (long_end['status'], long_end['priority']) == ('CANCELED', 7)
    assert stopped.status_code == 200 and stopped.json()['task_name'] == 'system/stop'
    answers = {a['robot_id']: a for a in stop_all.json()['answers']}
    assert list(answers) == [ROBOT, 'robot2']
    assert answers[ROBOT]['ok'] is True and answers[ROBOT]['task']['status'] == 'DONE'
    assert answers['robot2']['ok'] is False
    assert answers['robot2']['error']['code'] == 'robot_offline'


# ---- "any robot": one busy, one offline, one free ------------------------------------------


def test_any_robot_is_the_free_one_of_a_busy_an_offline_and_a_free_robot(
    two_demo_robots: None,
    console: ConsoleProcess,
    start_robot_on: Callable[..., SimulatedRobot],
) -> None:
    start_robot_on('robot3').go_offline()
    far = {'task_name': NAVIGATE, 'task_data': {'x': 50.0, 'y': 0.0}, 'task_id': 'far'}
    near = {'task_name': NAVIGATE, 'task_data': {'x': 0.3, 'y': 0.0}}
    with console.client(OPERATOR) as alice:
        online(alice, 'robot1', NAVIGATE)
        online(alice, 'robot2', NAVIGATE)
        wait_for(
            lambda: robot_state(alice, 'robot3'),
            lambda r: r.get('connection_state') == 'OFFLINE',
            'robot3 OFFLINE',
        )
        assert alice.post('/api/robots/robot1/tasks/start', json=far).status_code == 202
        active(alice, 'robot1', 'far', 'IN_PROGRESS')
        chosen = alice.post('/api/fleet/start', json=near)
        offline_alone = alice.post('/api/fleet/start', json={**near, 'robots': ['robot3']})
        ended = stored(alice, chosen.json()['task_id'])
        stopped = alice.post('/api/robots/robot1/stop')
        far_end = stored(alice, 'far')

    assert chosen.status_code == 202, chosen.text
    answer = chosen.json()
    assert answer['robot_id'] == 'robot2'
    assert answer['reason'] == (
        f'robot2 is ONLINE, declares {NAVIGATE}, its resources for it are free, 0 active tasks'
    )
    assert answer['others'] == {
        'robot1': f'its resources for {NAVIGATE} are busy',
        'robot3': 'OFFLINE',
    }
    assert (ended['robot_id'], ended['status'], ended['source']) == (
        'robot2',
        'DONE',
        'CLOUD:alice',
    )
    assert offline_alone.status_code == 409
    assert offline_alone.json()['error']['code'] == 'robot_offline'
    assert stopped.status_code == 200, stopped.text
    assert (far_end['robot_id'], far_end['status']) == ('robot1', 'CANCELED')
