"""Roles on the console's doors (issue 38, item 3): what viewer, operator and admin tokens may do
on every route, from one table that must list every route of the application, and with every
system task however a request asks for it (by its effect, as on the web gateway: the same
code). The routes are tried over HTTP on a real console process, on a real mosquitto."""

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from task_manager_mqtt.testing import BrokerProcess
from task_manager_web import doors_testing
from task_manager_web.doors.task_roles import SYSTEM_TASK_ROLES
from task_manager_web.doors.tokens import generated_token
from task_manager_web.doors_testing import ADMIN, NAMES, OPERATOR, PUBLIC, RANKS, VIEWER

from task_manager.core.names import SYSTEM_TASK_NAMES
from task_manager_console.app import Settings, create_app
from task_manager_console.doors_testing import ConsoleProcess
from task_manager_console.fleet import Fleet
from task_manager_console.store.fleet_history import FleetHistory
from task_manager_console.testing import CONSOLE_USER, ROBOTS

# key: (method, route path) of every route of the console ('MOUNT' for a folder of files),
# value: the role it needs (PUBLIC: none). A route added to the app needs a line here.
ROUTE_ROLES: dict[tuple[str, str], str | None] = {
    ('GET', '/'): PUBLIC,
    ('GET', '/openapi.json'): PUBLIC,
    ('MOUNT', '/static'): PUBLIC,
    ('MOUNT', '/web-static'): PUBLIC,
    ('GET', '/api/health'): PUBLIC,
    ('GET', '/api/whoami'): VIEWER,
    ('GET', '/metrics'): VIEWER,
    ('GET', '/api/robots'): VIEWER,
    ('GET', '/api/robots/{robot_id}'): VIEWER,
    ('GET', '/api/history'): VIEWER,
    ('GET', '/api/events'): VIEWER,
    ('POST', '/api/robots/{robot_id}/tasks/start'): OPERATOR,
    ('POST', '/api/robots/{robot_id}/missions'): OPERATOR,
    ('POST', '/api/robots/{robot_id}/tasks/cancel'): OPERATOR,
    ('POST', '/api/robots/{robot_id}/tasks/pause'): OPERATOR,
    ('POST', '/api/robots/{robot_id}/tasks/resume'): OPERATOR,
    ('POST', '/api/robots/{robot_id}/tasks/{task_id:path}/confirm'): OPERATOR,
    ('POST', '/api/robots/{robot_id}/stop'): OPERATOR,
    ('POST', '/api/fleet/start'): OPERATOR,
    ('POST', '/api/fleet/stop'): OPERATOR,
    ('POST', '/api/robots/{robot_id}/tasks/reprioritize'): ADMIN,
}
ROUTE_CASES = doors_testing.route_cases(ROUTE_ROLES)
FIB = {'task_name': 'fib', 'task_data': {'order': 1}}
# key: a way of asking for a system task, value: its request's path, the field a refusal
# names, and the answer when it is let in (no robot is on the broker: nothing can start)
WAYS: dict[str, tuple[str, str, tuple[int, str]]] = {
    'a start on a robot': (
        '/api/robots/robot1/tasks/start', 'task_name', (404, 'unknown_robot')
    ),
    'a mission step on a robot': (
        '/api/robots/robot1/missions', 'subtasks.1.task_name', (404, 'unknown_robot')
    ),
    'a step in JSON text': (
        '/api/robots/robot1/tasks/start', 'task_data.subtasks.1.task_name',
        (404, 'unknown_robot'),
    ),
    'a start on any robot': ('/api/fleet/start', 'task_name', (409, 'no_robot')),
}  # fmt: skip
SYSTEM_TASK_CASES = [
    pytest.param(task, way, caller, id=f'{task} as {way} by {caller}')
    for task in sorted(SYSTEM_TASK_NAMES)
    for way in WAYS
    for caller in (VIEWER, OPERATOR, ADMIN)
]


def url_of(path: str) -> str:
    """A route's path with ids in its parameters."""
    return path.replace('{robot_id}', 'robot1').replace('{task_id:path}', 'some-id')


def asking_for(task: str, way: str) -> dict[str, Any]:
    """The body of a request that asks for `task` the `way` said (its step after a fib)."""
    if way in ('a start on a robot', 'a start on any robot'):
        return {'task_name': task, 'task_data': {}}
    steps = [FIB, {'task_name': task, 'task_data': {}}]
    if way == 'a mission step on a robot':
        return {'subtasks': steps}
    text_steps = [{**step, 'task_data': '{}' if step['task_name'] == task else '{"order": 1}'}
                  for step in steps]  # fmt: skip
    return {'task_name': 'system/mission', 'task_data': {'subtasks': text_steps}}


@pytest.fixture(scope='module')
def console(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ConsoleProcess]:
    """A console on a broker where no robot is: nothing a request asks for can happen."""
    folder = tmp_path_factory.mktemp('roles')
    broker = BrokerProcess(folder / 'broker', robots=ROBOTS, clouds=[CONSOLE_USER])
    broker.start()
    console = ConsoleProcess(broker, f'sqlite:///{folder / "fleet.sqlite"}', folder / 'console')
    yield console
    try:
        assert console.stop() == 0, '\n'.join(console.lines)
    finally:
        broker.stop()


# ---- every route, every role ----------------------------------------------------------------


def test_the_table_has_every_route_of_the_console(tmp_path: Path) -> None:
    history = FleetHistory.open(f'sqlite:///{tmp_path / "fleet.sqlite"}')
    try:
        fleet = Fleet('mqtt://console@127.0.0.1:1', history)  # never started
        app = create_app(fleet, Settings(tokens=(generated_token(),)))
    finally:
        history.close()
    routes = doors_testing.routes_of(app)

    assert routes - ROUTE_ROLES.keys() == set(), 'a route without a role: add it to ROUTE_ROLES'
    assert ROUTE_ROLES.keys() - routes == set(), 'a route in ROUTE_ROLES the console lacks'


@pytest.mark.parametrize(('method', 'path', 'needed', 'caller'), ROUTE_CASES)
def test_each_route_lets_in_the_roles_it_needs_and_refuses_the_others(
    console: ConsoleProcess, method: str, path: str, needed: str | None, caller: str | None
) -> None:
    with console.client(caller) as client:
        response = doors_testing.request(client, method, url_of(path))

    doors_testing.check_role_answer(response, method, url_of(path), needed, caller)


@pytest.mark.parametrize('caller', [VIEWER, OPERATOR, ADMIN])
def test_whoami_says_the_role_and_name_of_the_token(console: ConsoleProcess, caller: str) -> None:
    with console.client(caller) as client:
        response = client.get('/api/whoami')

    assert (response.status_code, response.json()) == (200, {'role': caller, 'name': NAMES[caller]})


# ---- every system task, every way of asking for it, every role -----------------------------


def test_every_system_task_has_a_role() -> None:
    assert SYSTEM_TASK_ROLES.keys() == SYSTEM_TASK_NAMES


@pytest.mark.parametrize(('task', 'way', 'caller'), SYSTEM_TASK_CASES)
def test_a_system_task_needs_its_role_however_a_request_asks_for_it(
    console: ConsoleProcess, task: str, way: str, caller: str
) -> None:
    path, field, let_in = WAYS[way]
    with console.client(caller) as client:
        response = client.post(path, json=asking_for(task, way))

    needed = max(RANKS[OPERATOR], SYSTEM_TASK_ROLES[task].value)
    if RANKS[caller] >= needed:  # let in: refused later, for want of a robot
        assert (response.status_code, response.json()['error']['code']) == let_in, response.text
    elif caller == VIEWER:  # below the route's own role
        assert response.status_code == 403, response.text
        assert response.json()['error']['message'].startswith(f'POST {path} needs role')
    else:
        assert response.status_code == 403, response.text
        assert response.json()['error'] == {
            'code': 'forbidden',
            'message': f'starting {task} needs role admin; this token is operator',
            'field': field,
        }


@pytest.mark.parametrize('path', ['/api/robots/robot1/tasks/start', '/api/fleet/start'])
def test_a_priority_of_ones_own_is_an_admins(console: ConsoleProcess, path: str) -> None:
    body = {**FIB, 'priority': 90}
    with console.client(OPERATOR) as alice, console.client(ADMIN) as admin:
        refused = alice.post(path, json=body)
        let_in = admin.post(path, json=body)

    assert refused.status_code == 403, refused.text
    assert refused.json()['error']['field'] == 'priority'
    assert let_in.status_code in (404, 409), let_in.text  # no robot to start it on
