"""Roles on the web gateway (issue 30, item 3): what viewer, operator and admin tokens may do
on every route, from one table, and with every system task, however a request asks for it
(issue 37, item 3: by its effect, not by the route); the token's name as the source of what it
starts. The routes are tried over HTTP on real gateway processes (with a real Task Manager
where something could happen). The token file and the gateway's access: test_web_tokens.py."""

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from task_manager.client import TaskManagerClient
from task_manager.core.names import SYSTEM_TASK_NAMES
from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check, wait_until
from task_manager_web import doors_testing
from task_manager_web.app import Settings, create_app
from task_manager_web.doors import task_roles
from task_manager_web.doors.task_roles import (
    SYSTEM_TASK_ROLES,
    Need,
    UnreadableTaskDataError,
    needed_to_start,
    with_runs_priority,
)
from task_manager_web.doors.tokens import Role, generated_token
from task_manager_web.doors_testing import ADMIN, OPERATOR, PUBLIC, RANKS, TOKEN_FILE, VIEWER
from task_manager_web.testing import GatewayProcess

# key: (method, route path) of every route of the gateway ('MOUNT' for a folder of files),
# value: the role it needs (PUBLIC: none). A route added to the app needs a line here.
ROUTE_ROLES: dict[tuple[str, str], str | None] = {
    ('GET', '/'): PUBLIC,
    ('GET', '/docs'): PUBLIC,
    ('GET', '/openapi.json'): PUBLIC,
    ('MOUNT', '/static'): PUBLIC,
    ('MOUNT', '/swagger'): PUBLIC,
    ('GET', '/api/health'): PUBLIC,
    ('GET', '/api/whoami'): VIEWER,
    ('GET', '/metrics'): VIEWER,
    ('GET', '/api/tasks'): VIEWER,
    ('GET', '/api/active'): VIEWER,
    ('GET', '/api/tasks/{task_id:path}'): VIEWER,
    ('GET', '/api/tasks/{task_id:path}/why'): VIEWER,
    ('GET', '/api/history'): VIEWER,
    ('GET', '/api/events'): VIEWER,
    ('GET', '/api/schedules'): VIEWER,
    ('POST', '/api/tasks/start'): OPERATOR,
    ('POST', '/api/missions'): OPERATOR,
    ('POST', '/api/tasks/cancel'): OPERATOR,
    ('POST', '/api/stop'): OPERATOR,
    ('POST', '/api/tasks/pause'): OPERATOR,
    ('POST', '/api/tasks/resume'): OPERATOR,
    ('POST', '/api/tasks/{task_id:path}/confirm'): OPERATOR,
    ('POST', '/api/tasks/reprioritize'): ADMIN,
    ('POST', '/api/schedules'): ADMIN,
    ('PATCH', '/api/schedules/{schedule_id:path}'): ADMIN,
    ('DELETE', '/api/schedules/{schedule_id:path}'): ADMIN,
}
# key: a system task, value: the role that may run it, whichever request asks for it: that of
# the route that runs it (POST /api/tasks/reprioritize: admin). A system task added to the
# Task Manager needs a line here.
SYSTEM_TASK_ROLES_EXPECTED: dict[str, str] = {
    'system/mission': OPERATOR,
    'system/wait': OPERATOR,
    'system/confirm': OPERATOR,
    'system/cancel_task': OPERATOR,
    'system/cancel_tasks': OPERATOR,
    'system/stop': OPERATOR,
    'system/pause': OPERATOR,
    'system/resume': OPERATOR,
    'system/reprioritize': ADMIN,
    'system/schedule': ADMIN,
    'system/unschedule': ADMIN,
    'system/enable_schedule': ADMIN,
}
ROUTE_CASES = doors_testing.route_cases(ROUTE_ROLES)


def url_of(path: str) -> str:
    """A route's path with an id in its parameters."""
    return path.replace('{task_id:path}', 'some-id').replace('{schedule_id:path}', 'some-id')


def no_client() -> TaskManagerClient:
    raise AssertionError('the application is not started here')


def client_of(gateway: GatewayProcess, caller: str | None) -> httpx.Client:
    return doors_testing.client_of(gateway.url, caller, TIMEOUT_SEC)


@pytest.fixture(scope='module')
def token_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp('roles') / 'tokens'
    path.write_text(TOKEN_FILE)
    return path


@pytest.fixture(scope='module')
def alone(token_file: Path) -> Iterator[GatewayProcess]:
    """A gateway that reaches no Task Manager: nothing a request asks for can happen."""
    gateway = GatewayProcess(token_file)
    yield gateway
    assert gateway.stop() == 0, '\n'.join(gateway.log_lines)


@pytest.fixture
def gateway(robot: Robot, token_file: Path) -> Iterator[GatewayProcess]:
    """A gateway of a real Task Manager, once it reaches it."""
    gateway = GatewayProcess(token_file)
    with client_of(gateway, VIEWER) as viewer:
        wait_until(lambda: viewer.get('/api/health').json()['connected'], 'gateway connected')
    yield gateway
    assert gateway.stop() == 0, '\n'.join(gateway.log_lines)


# ---- every route, every role ----------------------------------------------------------------


def test_the_table_has_every_route_of_the_gateway() -> None:
    routes = doors_testing.routes_of(create_app(Settings(tokens=(generated_token(),)), no_client))

    assert routes - ROUTE_ROLES.keys() == set(), 'a route without a role: add it to ROUTE_ROLES'
    assert ROUTE_ROLES.keys() - routes == set(), 'a route in ROUTE_ROLES the gateway lacks'


@pytest.mark.ros
@pytest.mark.parametrize(('method', 'path', 'needed', 'caller'), ROUTE_CASES)
def test_each_route_lets_in_the_roles_it_needs_and_refuses_the_others(
    alone: GatewayProcess, method: str, path: str, needed: str | None, caller: str | None
) -> None:
    with client_of(alone, caller) as client:
        response = doors_testing.request(client, method, url_of(path))

    doors_testing.check_role_answer(response, method, url_of(path), needed, caller)
    if response.status_code in (401, 403):
        check(response.json(), 'error')


@pytest.mark.ros
@pytest.mark.parametrize(('caller', 'name'), [(VIEWER, 'victor'), (OPERATOR, 'alice'), (ADMIN, '')])
def test_whoami_says_the_role_and_name_of_the_token(
    alone: GatewayProcess, caller: str, name: str
) -> None:
    with client_of(alone, caller) as client:
        response = client.get('/api/whoami')

    assert (response.status_code, response.json()) == (200, {'role': caller, 'name': name})


@pytest.mark.ros
def test_reading_without_token_is_a_viewers_and_nothing_more(token_file: Path) -> None:
    gateway = GatewayProcess(token_file, '--read-without-token')
    try:
        with client_of(gateway, None) as anyone, client_of(gateway, OPERATOR) as alice:
            whoami = anyone.get('/api/whoami')
            start = anyone.post('/api/tasks/start', json={'task_name': 'fib'})
            known = alice.get('/api/whoami')
    finally:
        assert gateway.stop() == 0, '\n'.join(gateway.log_lines)

    assert whoami.json() == {'role': VIEWER, 'name': ''}
    assert start.status_code == 401
    assert known.json() == {'role': OPERATOR, 'name': 'alice'}


# ---- every system task, every way of asking for it, every role -----------------------------

FIB = {'task_name': 'fib', 'task_data': {'order': 1}}
SCHEDULE = {**FIB, 'schedule_id': 'nightly', 'cron': '0 2 * * *'}
STEP_IN_TEXT = 'a step of system/mission, its task_data JSON text'
# key: a way of asking for a system task, value: its request's method and path, and the field
# a refusal names
WAYS: dict[str, tuple[str, str, str]] = {
    'a start': ('POST', '/api/tasks/start', 'task_name'),
    'a mission step': ('POST', '/api/missions', 'subtasks.1.task_name'),
    STEP_IN_TEXT: ('POST', '/api/tasks/start', 'task_data.subtasks.1.task_name'),
}
SYSTEM_TASK_CASES = [
    pytest.param(task, way, caller, id=f'{task} as {way} by {caller}')
    for task in SYSTEM_TASK_ROLES_EXPECTED
    for way in WAYS
    for caller in (VIEWER, OPERATOR, ADMIN)
]


def asking_for(task: str, way: str) -> dict[str, Any]:
    """The body of a request that asks for `task` the `way` said (its step after a fib)."""
    steps = [FIB, {'task_name': task, 'task_data': {}}]
    if way == 'a start':
        return {'task_name': task, 'task_data': {}}
    if way == 'a mission step':
        return {'subtasks': steps}
    text_steps = [{**step, 'task_data': json.dumps(step['task_data'])} for step in steps]
    return {'task_name': 'system/mission', 'task_data': {'subtasks': text_steps}}


def test_the_table_has_every_system_task_and_the_gateway_its_roles() -> None:
    assert SYSTEM_TASK_ROLES_EXPECTED.keys() == SYSTEM_TASK_NAMES, 'a system task without role'
    assert {task: role.label for task, role in SYSTEM_TASK_ROLES.items()} == (
        SYSTEM_TASK_ROLES_EXPECTED
    )


@pytest.mark.ros
@pytest.mark.parametrize(('task', 'way', 'caller'), SYSTEM_TASK_CASES)
def test_a_system_task_needs_its_role_however_a_request_asks_for_it(
    alone: GatewayProcess, task: str, way: str, caller: str
) -> None:
    method, path, field = WAYS[way]
    with client_of(alone, caller) as client:
        response = client.request(method, path, json=asking_for(task, way))

    needed = max(RANKS[OPERATOR], RANKS[SYSTEM_TASK_ROLES_EXPECTED[task]])
    if RANKS[caller] >= needed:  # let in: refused later, for want of a Task Manager
        assert response.status_code == 503, response.text
    elif caller == VIEWER:  # below the route's own role
        assert response.status_code == 403, response.text
        assert response.json()['error']['message'].startswith(f'{method} {path} needs role')
    else:
        assert response.status_code == 403, response.text
        assert check(response.json(), 'error')['error'] == {
            'code': 'forbidden',
            'message': f'starting {task} needs role admin; this token is operator',
            'field': field,
        }


# ---- over a real Task Manager ---------------------------------------------------------------


@pytest.mark.ros
def test_a_request_beyond_the_role_does_nothing(robot: Robot, gateway: GatewayProcess) -> None:
    with client_of(gateway, VIEWER) as viewer, client_of(gateway, OPERATOR) as alice:
        refused = [
            viewer.post('/api/tasks/start', json={**FIB, 'task_id': 'by-viewer'}),
            viewer.post('/api/missions', json={'subtasks': [FIB], 'task_id': 'm-viewer'}),
            viewer.post('/api/tasks/cancel', json={'task_ids': ['x']}),
            viewer.post('/api/stop'),
            viewer.post('/api/tasks/pause', json={'task_ids': ['x']}),
            alice.post('/api/schedules', json=SCHEDULE),
            alice.post('/api/tasks/reprioritize', json={'task_ids': ['x'], 'priority': 9}),
            alice.post('/api/tasks/start', json={**FIB, 'task_id': 'urgent', 'priority': 90}),
        ]
        active = viewer.get('/api/active').json()
        history = viewer.get('/api/history').json()
        schedules = viewer.get('/api/schedules').json()

    assert [r.status_code for r in refused] == [403] * len(refused), [r.text for r in refused]
    assert {check(r.json(), 'error')['error']['code'] for r in refused} == {'forbidden'}
    assert (active, history, schedules) == ([], [], [])
    assert not robot.fib.goals.items
    priority = refused[-1].json()['error']
    assert priority['field'] == 'priority'
    assert priority['message'] == (
        'a start that gives a priority needs role admin; this token is operator (leave '
        "priority out: the task's declared priority applies)"
    )


@pytest.mark.ros
def test_an_operator_cannot_run_an_admins_system_task_by_starting_it(
    robot: Robot, gateway: GatewayProcess
) -> None:
    """Issue 37, item 3: /api/tasks/reprioritize and /api/schedules refused an operator, but a
    start of system/reprioritize, system/schedule (its runs at the highest priority),
    system/unschedule or system/enable_schedule, or a mission with one as a step, ran."""
    sneaky = {
        'schedule_id': 'sneaky', 'task_name': 'fib', 'task_data': '{"order": 1}',
        'cron': '0 2 * * *', 'options': {'has_priority': True, 'priority': 2**31 - 1},
    }  # fmt: skip
    nightly = {'schedule_ids': ['nightly']}
    with client_of(gateway, OPERATOR) as alice, client_of(gateway, ADMIN) as admin:
        assert admin.post('/api/schedules', json=SCHEDULE).json()['scheduled']
        assert alice.post('/api/tasks/start', json={**FIB, 'task_id': 'running'}).is_success
        robot.fib.wait_for_goals(1, TIMEOUT_SEC)
        reprioritize = {'task_ids': ['running'], 'priority': 2**31 - 1}
        refused = [
            alice.post('/api/tasks/start', json={'task_name': name, 'task_data': data})
            for name, data in [
                ('system/reprioritize', reprioritize),
                ('system/schedule', sneaky),
                ('system/unschedule', nightly),
                ('system/enable_schedule', {**nightly, 'enabled': False}),
                ('system/mission', {'subtasks': [
                    {'task_name': 'system/reprioritize', 'task_data': json.dumps(reprioritize)}
                ]}),
            ]
        ] + [
            alice.post('/api/missions', json={'subtasks': [
                {'task_name': 'system/unschedule', 'task_data': nightly}
            ]}),
        ]  # fmt: skip
        schedules = alice.get('/api/schedules').json()
        running = alice.get('/api/tasks/running').json()
        robot.fib.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
        by_alice = {'source': 'WEB:alice'}
        history = wait_until(lambda: alice.get('/api/history', params=by_alice).json(), 'fib')

    assert [r.status_code for r in refused] == [403] * len(refused), [r.text for r in refused]
    assert {check(r.json(), 'error')['error']['code'] for r in refused} == {'forbidden'}
    assert [(s['schedule_id'], s['enabled']) for s in schedules] == [('nightly', True)]
    assert running['priority'] != 2**31 - 1
    assert 'reprioritized' not in {d['decision'] for d in running['decisions']}
    assert [(t['task_id'], t['task_name']) for t in history] == [('running', 'fib')]


@pytest.mark.ros
def test_the_history_says_which_token_started_a_task(robot: Robot, gateway: GatewayProcess) -> None:
    with client_of(gateway, OPERATOR) as alice, client_of(gateway, ADMIN) as admin:
        by_alice = alice.post(
            '/api/tasks/start',
            params={'wait': 'true'},
            json={'task_name': 'instant', 'task_data': {'data': True}, 'task_id': 'alices'},
        )
        by_admin = admin.post(
            '/api/tasks/start',
            params={'wait': 'true'},
            json={'task_name': 'instant', 'task_data': {'data': True}, 'priority': 5},
        )
        alices = alice.get('/api/history', params={'source': 'WEB:alice'}).json()

    assert by_alice.status_code == 200, by_alice.text
    assert check(by_alice.json(), 'started')['task']['source'] == 'WEB:alice'
    assert check(by_admin.json(), 'started')['task']['source'] == 'WEB'  # a token without name
    assert [(t['task_id'], t['source'], t['status']) for t in alices] == [
        ('alices', 'WEB:alice', 'DONE')
    ]


# ---- what a start needs, without a network -------------------------------------------------


def test_what_a_start_needs_is_what_it_starts_in_turn() -> None:
    reprioritize = {'task_name': 'system/reprioritize', 'task_data': '{}'}
    # a step that is a mission (the node refuses it, but only once it reads it), its task_data
    # JSON text, read as the Task Manager reads it
    in_text = {'task_name': 'system/mission', 'task_data': json.dumps({'subtasks': [reprioritize]})}
    schedule_of_fib = {'task_name': 'fib', 'task_data': '{"order": 1}'}

    assert needed_to_start('fib', {}) == Need(Role.OPERATOR, 'starting fib', 'task_name')
    assert needed_to_start('system/mission', {'subtasks': [FIB, reprioritize]}) == Need(
        Role.ADMIN, 'starting system/reprioritize', 'task_data.subtasks.1.task_name'
    )
    assert needed_to_start('system/mission', {'subtasks': [FIB, in_text]}) == Need(
        Role.ADMIN,
        'starting system/reprioritize',
        'task_data.subtasks.1.task_data.subtasks.0.task_name',
    )
    assert needed_to_start('system/schedule', schedule_of_fib) == Need(
        Role.ADMIN, 'starting system/schedule', 'task_name'
    )


@pytest.mark.parametrize('options', [{'priority': 0}, {'has_priority': True}])
def test_a_schedules_runs_priority_needs_an_admin_whatever_schedule_itself_needs(
    monkeypatch: pytest.MonkeyPatch, options: dict[str, Any]
) -> None:
    monkeypatch.setattr(
        task_roles, 'SYSTEM_TASK_ROLES', {**SYSTEM_TASK_ROLES, 'system/schedule': Role.OPERATOR}
    )
    schedule = {'task_name': 'fib', 'task_data': '{"order": 1}', 'cron': '0 2 * * *'}

    assert needed_to_start('system/schedule', schedule).role is Role.OPERATOR
    assert needed_to_start('system/schedule', {**schedule, 'options': options}) == Need(
        Role.ADMIN, 'a priority of its runs', 'task_data.options.priority'
    )
    assert with_runs_priority(Need(Role.OPERATOR, 'starting fib', 'task_name'), True, 'x') == (
        Need(Role.ADMIN, 'a priority of its runs', 'x')
    )


def test_a_task_data_in_json_text_that_is_not_plain_json_cannot_be_checked() -> None:
    twice = {'task_name': 'system/schedule', 'task_data': '{"task_name": "fib", "task_name": "x"}'}

    with pytest.raises(UnreadableTaskDataError) as unreadable:
        needed_to_start('system/mission', {'subtasks': [twice]})

    assert unreadable.value.field == 'task_data.subtasks.0.task_data'
    assert "the key 'task_name' is given twice" in str(unreadable.value)


@pytest.mark.ros
def test_a_start_whose_effect_cannot_be_read_is_refused_422(alone: GatewayProcess) -> None:
    step = {'task_name': 'system/schedule', 'task_data': '{"task_name": "fib"'}
    with client_of(alone, ADMIN) as admin:
        response = admin.post(
            '/api/tasks/start',
            json={'task_name': 'system/mission', 'task_data': {'subtasks': [step]}},
        )

    assert response.status_code == 422, response.text
    error = check(response.json(), 'error')['error']
    assert (error['code'], error['field']) == ('invalid_request', 'task_data.subtasks.0.task_data')
    assert error['message'].startswith('task_data.subtasks.0.task_data: not valid JSON')
