"""Roles on the web gateway (issue 30, item 3): what viewer, operator and admin tokens may do
on every route, from one table, and with every system task, however a request asks for it
(issue 37, item 3: by its effect, not by the route); the token file; the token's name as the
source of what it starts. The routes are tried over HTTP on real gateway processes (with a
real Task Manager where something could happen)."""

import json
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from starlette.routing import Mount, Route

from task_manager.client import TaskManagerClient
from task_manager.core.names import SYSTEM_TASK_NAMES
from task_manager.secret_file import exposure_warning
from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check, wait_until
from task_manager_web.app import Settings, create_app
from task_manager_web.doors import task_roles
from task_manager_web.doors.access import Access, check_start_priority
from task_manager_web.doors.task_roles import (
    SYSTEM_TASK_ROLES,
    Need,
    UnreadableTaskDataError,
    needed_to_start,
    with_runs_priority,
)
from task_manager_web.doors.tokens import (
    GENERATED_NAME,
    Role,
    Token,
    TokenFileError,
    generated_token,
    parse_tokens,
)
from task_manager_web.errors import ApiError
from task_manager_web.testing import GATEWAY_EXECUTABLE, GatewayProcess

VIEWER, OPERATOR, ADMIN = 'viewer', 'operator', 'admin'
PUBLIC = None
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
RANKS = {VIEWER: 1, OPERATOR: 2, ADMIN: 3}
# key: a role, value: its token in TOKEN_FILE
TOKENS = {
    VIEWER: 'viewer-token-0123456789',
    OPERATOR: 'operator-token-0123456789',
    ADMIN: 'admin-token-0123456789',
}
TOKEN_FILE = f"""# the tokens of the role tests
viewer   {TOKENS[VIEWER]}   victor
operator {TOKENS[OPERATOR]} alice   # the operator of the tests

admin    {TOKENS[ADMIN]}
"""
CALLERS = (None, VIEWER, OPERATOR, ADMIN)
"""Who sends a request: no token, or the token of a role."""
ROUTE_CASES = [
    pytest.param(method, path, needed, caller, id=f'{method} {path} as {caller or "nobody"}')
    for (method, path), needed in ROUTE_ROLES.items()
    if method != 'MOUNT'
    for caller in CALLERS
]


def url_of(path: str) -> str:
    """A route's path with an id in its parameters."""
    return path.replace('{task_id:path}', 'some-id').replace('{schedule_id:path}', 'some-id')


def request(client: httpx.Client, method: str, path: str) -> httpx.Response:
    """`method path`, with `{}` for a body (what it holds is checked after the role)."""
    body: dict[str, Any] | None = {} if method in ('POST', 'PATCH') else None
    if path == '/api/events':  # its answer never ends: its head only, or its error
        with client.stream(method, url_of(path)) as response:
            if response.status_code != 200:
                response.read()
            return response
    return client.request(method, url_of(path), json=body)


def no_client() -> TaskManagerClient:
    raise AssertionError('the application is not started here')


def client_of(gateway: GatewayProcess, caller: str | None) -> httpx.Client:
    headers = {'Authorization': f'Bearer {TOKENS[caller]}'} if caller else {}
    return httpx.Client(base_url=gateway.url, headers=headers, timeout=TIMEOUT_SEC)


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
    app = create_app(Settings(tokens=(generated_token(),)), no_client)
    routes = set()
    for route in app.routes:
        if isinstance(route, Mount):
            routes.add(('MOUNT', route.path))
        elif isinstance(route, Route):
            routes.update((method, route.path) for method in (route.methods or set()) - {'HEAD'})
        else:
            routes.add(('?', repr(route)))

    assert routes - ROUTE_ROLES.keys() == set(), 'a route without a role: add it to ROUTE_ROLES'
    assert ROUTE_ROLES.keys() - routes == set(), 'a route in ROUTE_ROLES the gateway lacks'


@pytest.mark.ros
@pytest.mark.parametrize(('method', 'path', 'needed', 'caller'), ROUTE_CASES)
def test_each_route_lets_in_the_roles_it_needs_and_refuses_the_others(
    alone: GatewayProcess, method: str, path: str, needed: str | None, caller: str | None
) -> None:
    with client_of(alone, caller) as client:
        response = request(client, method, path)

    if needed is PUBLIC or (caller and RANKS[caller] >= RANKS[needed]):
        assert response.status_code not in (401, 403), response.text
    elif caller is None:
        assert response.status_code == 401, response.text
        assert check(response.json(), 'error')['error']['code'] == 'unauthorized'
    else:
        assert response.status_code == 403, response.text
        error = check(response.json(), 'error')['error']
        assert error == {
            'code': 'forbidden',
            'message': f'{method} {url_of(path)} needs role {needed}; this token is {caller}',
            'field': '',
        }


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


# ---- the token file and the gateway's access, without a network ----------------------------


def test_a_token_file_holds_roles_tokens_and_names_with_comments() -> None:
    tokens = parse_tokens(TOKEN_FILE, 'tokens')

    assert tokens == (
        Token(TOKENS[VIEWER], Role.VIEWER, 'victor'),
        Token(TOKENS[OPERATOR], Role.OPERATOR, 'alice'),
        Token(TOKENS[ADMIN], Role.ADMIN, ''),
    )


BARE = 'bare-0123456789ab'
"""A bare token of 16 characters, the shortest there may be."""


@pytest.mark.parametrize('text', [f'{BARE}\n', f'# the token\n\n  {BARE}  \n'])
def test_a_file_of_one_bare_token_holds_an_admin_token_without_name(text: str) -> None:
    assert parse_tokens(text, 'tokens') == (Token(BARE, Role.ADMIN, ''),)


@pytest.mark.parametrize(
    ('text', 'message'),
    [
        ('', 'tokens holds no token'),
        ('# nothing\n\n', 'tokens holds no token'),
        ('admin\n', 'tokens, line 1: a role without a token'),
        (
            f'admin {TOKENS[ADMIN]}\n{TOKENS[VIEWER]}\n',
            'tokens, line 2: 1 words; expected `ROLE TOKEN [NAME]`',
        ),
        (
            f'\nadmin {TOKENS[ADMIN]} root now\n',
            'tokens, line 2: 4 words; expected `ROLE TOKEN [NAME]`',
        ),
        (f'root {TOKENS[ADMIN]}\n', 'tokens, line 1: the first word is no role'),
        (f'operator {TOKENS[OPERATOR]} al/ice\n', 'tokens, line 1: a name is 1 to 64'),
        ('viewer alice\n', 'tokens, line 1: the token has 5 characters; at least 16'),
        ('operator short-012345678\n', 'tokens, line 1: the token has 15 characters; at least'),
        ('short-012345678\n', 'tokens, line 1: the token has 15 characters; at least 16'),
        ('# one bare token\nx\n', 'tokens, line 2: the token has 1 characters; at least 16'),
        (f'viewer={TOKENS[VIEWER]}\n', "tokens, line 1: a role word joined to a token by '='"),
        (f'Operator:{TOKENS[OPERATOR]}\n', "tokens, line 1: a role word joined to a token by ':'"),
        (f'Viewer {TOKENS[VIEWER]} victor\n', 'tokens, line 1: the first word is no role'),
        (f'viewers {TOKENS[VIEWER]}\n', 'tokens, line 1: the first word is no role'),
        (f'viewer {TOKENS[VIEWER]}é\n', 'tokens, line 1: a token is printable ASCII'),
        (
            f'viewer {TOKENS[VIEWER]} a\n# b\nadmin {TOKENS[VIEWER]} b\n',
            'tokens, line 3: the same token as line 1',
        ),
        (
            f'viewer {TOKENS[VIEWER]} alice\noperator {TOKENS[OPERATOR]} alice\n',
            'tokens, line 2: the same name as line 1',
        ),
    ],
)
def test_a_bad_token_file_says_which_line_and_never_shows_a_token(text: str, message: str) -> None:
    with pytest.raises(TokenFileError) as raised:
        parse_tokens(text, 'tokens')

    assert str(raised.value).startswith(message)
    shown = (*TOKENS.values(), 'alice', 'short-012345678')
    assert not any(token in str(raised.value) for token in shown)


def test_the_gateway_does_not_start_with_a_bad_token_file(tmp_path: Path) -> None:
    token_file = tmp_path / 'tokens'
    token_file.write_text(f'admin {TOKENS[ADMIN]}\noperator {TOKENS[OPERATOR]} al/ice\n')

    ended = subprocess.run(
        [GATEWAY_EXECUTABLE, '--port', '0', '--token-file', str(token_file)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_SEC,
        check=False,
    )

    assert ended.returncode == 2
    assert f'--token-file {token_file}, line 2: a name is' in ended.stderr
    assert TOKENS[OPERATOR] not in ended.stderr + ended.stdout


def test_the_gateway_logs_the_warning_of_a_token_file_others_may_read(tmp_path: Path) -> None:
    token_file = tmp_path / 'tokens'
    token_file.write_text(TOKEN_FILE)
    token_file.chmod(0o644)

    gateway = GatewayProcess(token_file)

    assert gateway.stop() == 0
    warnings = [line for line in gateway.log_lines if line.startswith('[WARNING]')]
    assert warnings == [
        f'[WARNING] [task_manager_web]: --token-file {exposure_warning(token_file)}'
    ]


def test_the_token_made_without_a_file_is_an_admins_named_admin() -> None:
    token = generated_token()

    assert (token.role, token.name, len(token.secret)) == (Role.ADMIN, GENERATED_NAME, 32)
    assert generated_token().secret != token.secret


def http_scope(authorization: str) -> dict[str, Any]:
    headers = [(b'authorization', authorization.encode())] if authorization else []
    return {'type': 'http', 'headers': headers, 'client': ('10.0.0.7', 4242)}


def test_each_token_is_a_client_of_its_own_for_the_read_bound() -> None:
    access = Access(parse_tokens(TOKEN_FILE, 'tokens'))
    keys = [access.client_key(http_scope(f'Bearer {TOKENS[r]}')) for r in (VIEWER, OPERATOR, ADMIN)]

    assert keys[:2] == ['token:victor', 'token:alice']
    assert keys[2].startswith('token-sha256:') and TOKENS[ADMIN] not in keys[2]
    assert access.client_key(http_scope('Bearer wrong')) == 'address:10.0.0.7'
    assert access.client_key(http_scope('')) == 'address:10.0.0.7'


def test_the_source_is_the_gateways_then_the_tokens_name() -> None:
    access = Access(parse_tokens(TOKEN_FILE, 'tokens'), source='ROBOT_UI')

    alice = access.caller(TOKENS[OPERATOR], Role.OPERATOR, 'POST /api/stop')
    admin = access.caller(TOKENS[ADMIN], Role.ADMIN, 'POST /api/stop')

    assert (alice.source, alice.name, alice.role) == ('ROBOT_UI:alice', 'alice', Role.OPERATOR)
    assert (admin.source, admin.name) == ('ROBOT_UI', '')


def test_only_an_admin_starts_with_a_priority_of_its_own() -> None:
    access = Access(parse_tokens(TOKEN_FILE, 'tokens'))
    alice = access.caller(TOKENS[OPERATOR], Role.OPERATOR, 'POST /api/tasks/start')
    admin = access.caller(TOKENS[ADMIN], Role.OPERATOR, 'POST /api/tasks/start')

    check_start_priority(alice, None)
    check_start_priority(admin, 7)
    with pytest.raises(ApiError) as raised:
        check_start_priority(alice, 0)
    assert (raised.value.status, raised.value.field) == (403, 'priority')


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
