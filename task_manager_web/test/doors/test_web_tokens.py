"""The web gateway's token file (issue 30, item 3): roles, tokens and names, what a bad file
says (never a token), the gateway that does not start with one or warns of one others may
read, the token made without a file; and its access without a network: each token a client of
its own for the read bound, the source of what a token starts, a priority of one's own."""

import subprocess
from pathlib import Path
from typing import Any

import pytest

from task_manager.core.bounds import TOKEN_MIN_CHARACTERS
from task_manager.gateway.secret_file import exposure_warning
from task_manager.testing.gateway import TIMEOUT_SEC
from task_manager_web.doors.access import Access, check_start_priority
from task_manager_web.doors.tokens import (
    ADMIN_TOKEN_VARIABLE,
    GENERATED_NAME,
    Role,
    Token,
    TokenFileError,
    door_tokens,
    generated_token,
    parse_tokens,
)
from task_manager_web.doors_testing import ADMIN, OPERATOR, TOKEN_FILE, TOKENS, VIEWER
from task_manager_web.errors import ApiError
from task_manager_web.testing import GATEWAY_EXECUTABLE, GatewayProcess


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


def test_without_a_file_the_variables_token_is_the_admins_and_a_bad_one_is_refused() -> None:
    """TASK_MANAGER_WEB_ADMIN_TOKEN: what a launcher gives the gateway it starts again."""
    given = 'k' * TOKEN_MIN_CHARACTERS
    (token,) = door_tokens('task-manager-web', None, {ADMIN_TOKEN_VARIABLE: given})
    assert (token.secret, token.role, token.name) == (given, Role.ADMIN, GENERATED_NAME)
    (made,) = door_tokens('task-manager-web', None, {})
    assert made.secret != given and made.role is Role.ADMIN
    for bad in ('k' * (TOKEN_MIN_CHARACTERS - 1), 'with space ' * 4):
        with pytest.raises(SystemExit, match=f'{ADMIN_TOKEN_VARIABLE} is no token') as refused:
            door_tokens('task-manager-web', None, {ADMIN_TOKEN_VARIABLE: bad})
        assert bad not in str(refused.value)


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
