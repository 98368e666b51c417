"""Roles on the web gateway (issue 30, item 3): what viewer, operator and admin tokens may do
on every route, from one table; the token file; the token's name as the source of what it
starts. The routes are tried over HTTP on real gateway processes (with a real Task Manager
where something could happen)."""

import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from starlette.routing import Mount, Route

from task_manager.client import TaskManagerClient
from task_manager.secret_file import exposure_warning
from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check, wait_until
from task_manager_web.access import Access, check_start_priority
from task_manager_web.app import Settings, create_app
from task_manager_web.errors import ApiError
from task_manager_web.testing import GATEWAY_EXECUTABLE, GatewayProcess
from task_manager_web.tokens import (
    GENERATED_NAME,
    Role,
    Token,
    TokenFileError,
    generated_token,
    parse_tokens,
)

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


# ---- over a real Task Manager ---------------------------------------------------------------

FIB = {'task_name': 'fib', 'task_data': {'order': 1}}
SCHEDULE = {**FIB, 'schedule_id': 'nightly', 'cron': '0 2 * * *'}


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
