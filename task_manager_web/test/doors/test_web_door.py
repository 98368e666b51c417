"""The gateway's door against a real gateway process, without a Task Manager: what it answers
before any request reaches a node (headers, Host, token, body, slow heads, the access log).

One gateway serves the module: nothing here changes it. The last test has a gateway of its
own, with a Task Manager: what a body costs the door before it knows who sent it.
"""

import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from task_manager.core.bounds import TASK_DATA_MAX_BYTES
from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check, wait_until
from task_manager_web.testing import GatewayProcess

pytestmark = pytest.mark.ros

HEADER_TIMEOUT_SEC = 0.5
EXTRA_HOST = 'robot7.example'
SECURITY_HEADERS = {
    'x-frame-options': 'DENY',
    'x-content-type-options': 'nosniff',
    'referrer-policy': 'no-referrer',
}


@pytest.fixture(scope='module')
def gateway(tmp_path_factory: pytest.TempPathFactory) -> Iterator[GatewayProcess]:
    token_file = tmp_path_factory.mktemp('door') / 'token'
    token_file.write_text('door-token-0123456789\n')
    gateway = GatewayProcess(
        token_file,
        '--access-log',
        '--allowed-host',
        EXTRA_HOST,
        '--header-timeout-sec',
        str(HEADER_TIMEOUT_SEC),
    )
    yield gateway
    assert gateway.stop() == 0, '\n'.join(gateway.log_lines)


@pytest.fixture
def http(gateway: GatewayProcess) -> Iterator[httpx.Client]:
    headers = {'Authorization': f'Bearer {gateway.token}'}
    with httpx.Client(base_url=gateway.url, headers=headers, timeout=TIMEOUT_SEC) as client:
        yield client


def address(gateway: GatewayProcess) -> tuple[str, int]:
    url = httpx.URL(gateway.url)
    assert url.port is not None
    return url.host, url.port


def test_every_answer_carries_the_security_headers(http: httpx.Client) -> None:
    answers = {
        'dashboard': http.get('/'),
        'docs': http.get('/docs'),
        'health': http.get('/api/health'),
        'not found': http.get('/api/nothing'),
        'unauthorized': http.get('/api/active', headers={'Authorization': ''}),
        'refused host': http.get('/api/health', headers={'Host': 'evil.example'}),
    }

    for name, answer in answers.items():
        assert SECURITY_HEADERS.items() <= answer.headers.items(), name
        policy = answer.headers['content-security-policy']
        assert "default-src 'none'" in policy and "frame-ancestors 'none'" in policy, name
        assert "script-src 'self';" in policy and 'unsafe-eval' not in policy, name
    assert "style-src 'self';" in answers['docs'].headers['content-security-policy']
    assert 'server' not in answers['health'].headers


def test_docs_name_no_host_whatever_the_host_header_says(http: httpx.Client) -> None:
    docs = http.get('/docs', headers={'Host': f'{EXTRA_HOST}:8080'})

    assert docs.status_code == 200
    assert 'http' not in docs.text and EXTRA_HOST not in docs.text
    assert 'src="swagger/swagger-ui-bundle.js"' in docs.text
    for asset in ('swagger/swagger-ui-bundle.js', 'swagger/swagger-ui.css', 'static/docs.js'):
        assert http.get(f'/{asset}').status_code == 200, asset


@pytest.mark.parametrize(
    ('host', 'status'),
    [
        ('127.0.0.1', 200),
        ('localhost:8080', 200),
        ('LOCALHOST', 200),
        ('[::1]:8080', 200),
        (EXTRA_HOST, 200),
        ('evil.example', 400),
        ('127.0.0.1.evil.example:80', 400),
        ('', 400),
    ],
)
def test_only_the_gateways_own_names_are_answered(
    http: httpx.Client, host: str, status: int
) -> None:
    response = http.get('/api/health', headers={'Host': host})

    assert response.status_code == status, response.text
    if status == 400:
        error = check(response.json(), 'error')['error']
        assert error['code'] == 'host_not_allowed' and '--allowed-host' in error['message']


def test_a_request_without_a_host_is_refused(gateway: GatewayProcess) -> None:
    with socket.create_connection(address(gateway), timeout=TIMEOUT_SEC) as connection:
        connection.sendall(b'GET /api/health HTTP/1.0\r\n\r\n')
        reply = b''
        while chunk := connection.recv(65536):
            reply += chunk

    assert reply.startswith(b'HTTP/1.1 400 ')
    assert b'host_not_allowed' in reply


@pytest.mark.parametrize(
    ('authorization', 'challenge'),
    [(None, 'Bearer'), ('Bearer wrong', 'Bearer error="invalid_token"'), ('Basic eDp5', 'Bearer')],
)
def test_401_says_how_to_authenticate(
    gateway: GatewayProcess, authorization: str | None, challenge: str
) -> None:
    headers = {} if authorization is None else {'Authorization': authorization}
    with httpx.Client(base_url=gateway.url, headers=headers, timeout=TIMEOUT_SEC) as stranger:
        responses = [
            stranger.get('/api/active'),
            stranger.post('/api/stop'),
            stranger.get('/api/events', params={'token': 'wrong'} if 'wrong' in challenge else {}),
        ]

    for response in responses:
        assert response.status_code == 401
        assert response.headers['www-authenticate'] == challenge


def test_a_chunked_body_over_the_limit_is_413(http: httpx.Client) -> None:
    def chunks() -> Iterator[bytes]:
        yield b'{"task_name": "fib", "task_data": {"padding": "'
        for _ in range(40):
            yield b'x' * 65536
        yield b'"}}'

    response = http.post(
        '/api/tasks/start', content=chunks(), headers={'Content-Type': 'application/json'}
    )

    assert 'content-length' not in response.request.headers  # sent chunked
    assert response.status_code == 413
    assert check(response.json(), 'error')['error']['code'] == 'body_too_large'


@pytest.mark.parametrize(
    ('content', 'code', 'words'),
    [
        ('{"task_name": "fib", "task_data": ' + '[' * 5000 + ']' * 5000 + '}', 'nesting_too_deep',
         'deeper than 32 levels'),
        ('{"task_name": "fib", "task_data": ' + '{"a": ' * 33 + '1' + '}' * 33 + '}',
         'nesting_too_deep', 'deeper than 32'),
        ('{"task_name": "fib", "task_name": "x"}', 'invalid_request', "'task_name' is given twice"),
        ('{"task_name": "fib", "task_data": {"a": 1, "a": 2}}', 'invalid_request', 'twice'),
        ('{"task_name": "fib", "task_data": {"order": NaN}}', 'invalid_request', 'NaN'),
        ('{"task_name": "fib", "task_data": {"order": Infinity}}', 'invalid_request', 'Infinity'),
        ('{"task_name": "fib", "task_data": {"order": -Infinity}}', 'invalid_request', 'Infinity'),
        ('{"task_name": "fib", "task_data": {"order": 1e999}}', 'invalid_request', 'too large'),
        ('{"task_ids": ["a"], "x": "\\ud800"}', 'invalid_request', ''),
        ('{"task_name": "fib", "order": ' + '9' * 5000 + '}', 'invalid_request', 'digits'),
        (b'{"task_name": "\xff"}', 'invalid_request', 'not UTF-8 text: byte 0xff at offset 15'),
    ],
)  # fmt: skip
def test_json_a_parser_would_misread_is_refused_422_at_the_door(
    http: httpx.Client, content: str | bytes, code: str, words: str
) -> None:
    path = '/api/tasks/cancel' if 'task_ids' in str(content) else '/api/tasks/start'

    response = http.post(path, content=content, headers={'Content-Type': 'application/json'})

    assert response.status_code == 422, response.text
    error = check(response.json(), 'error')['error']
    assert error['code'] == code and words in error['message']


def test_a_head_sent_too_slowly_loses_its_connection(gateway: GatewayProcess) -> None:
    began = time.monotonic()
    with socket.create_connection(address(gateway), timeout=TIMEOUT_SEC) as connection:
        connection.sendall(b'GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n')  # no end
        closed = connection.recv(65536)
    held_sec = time.monotonic() - began

    assert closed == b''
    assert HEADER_TIMEOUT_SEC <= held_sec < HEADER_TIMEOUT_SEC + 2.0
    # a kept-alive connection gets the same deadline for its next request's head
    with socket.create_connection(address(gateway), timeout=TIMEOUT_SEC) as connection:
        connection.sendall(b'GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n')
        reply = b''
        while not reply.endswith(b'}'):  # the whole answer: its JSON body ends it
            reply += connection.recv(65536)
        assert reply.startswith(b'HTTP/1.1 200 ')
        connection.sendall(b'GET /api/health HTTP/1.1\r\n')
        assert connection.recv(65536) == b''


def test_the_access_log_has_every_request_and_no_token(
    gateway: GatewayProcess, http: httpx.Client
) -> None:
    http.get('/api/health', params={'probe': 'access-log', 'token': 'door-token-0123456789'})
    http.get('/api/health?probe=encoded&%74oken=secret-2')  # Starlette reads it as `token`

    plain = gateway.wait_for_log(r'probe=access-log', TIMEOUT_SEC)
    encoded = gateway.wait_for_log(r'probe=encoded', TIMEOUT_SEC)

    assert '"GET /api/health?probe=access-log&token=<removed> HTTP/1.1" 200' in plain
    assert 'token=<removed>' in encoded
    access_lines = [line for line in gateway.log_lines if ' HTTP/1.1" ' in line]
    assert not [line for line in access_lines if 'door-token' in line or 'secret-2' in line]


ESCAPED_QUOTES = b'"' + b'\\"' * (TASK_DATA_MAX_BYTES // 2 - 1)
"""1 MiB of `"\\"\\"...`, a string never closed: the door's depth check of old took 36 s for 128
kB of it (issue 37, item 4), the event loop blocked all along."""
STOP_MAX_SEC = 5.0
"""Far below the 36 s of old, with room for a loaded machine (more test processes than cores)."""


def test_a_large_body_without_a_token_does_not_delay_an_operators_stop(
    robot: Robot, tmp_path: Path
) -> None:
    token_file = tmp_path / 'tokens'
    token_file.write_text('operator operator-token-0123456789 alice\n')
    gateway = GatewayProcess(token_file)
    anyone = httpx.Client(base_url=gateway.url, timeout=TIMEOUT_SEC)
    alice = httpx.Client(
        base_url=gateway.url,
        headers={'Authorization': 'Bearer operator-token-0123456789'},
        timeout=TIMEOUT_SEC,
    )
    answers: list[httpx.Response] = []
    done = threading.Event()

    def send_bodies() -> None:
        """The large body, again and again, without a token, until the stop has its answer."""
        while not done.is_set():
            answers.append(
                anyone.post(
                    '/api/tasks/start',
                    content=ESCAPED_QUOTES,
                    headers={'Content-Type': 'application/json'},
                )
            )

    sender = threading.Thread(target=send_bodies)
    try:
        wait_until(lambda: alice.get('/api/health').json()['connected'], 'gateway connected')
        sender.start()
        wait_until(lambda: answers, 'the first large body answered')
        began = time.monotonic()
        stop = alice.post('/api/stop')
        stop_sec = time.monotonic() - began
        done.set()
        sender.join()
    finally:
        done.set()
        anyone.close()
        alice.close()
        assert gateway.stop() == 0, '\n'.join(gateway.log_lines)

    assert stop.status_code == 200, stop.text
    assert (stop.json()['status'], stop.json()['source']) == ('DONE', 'WEB:alice')
    assert stop_sec < STOP_MAX_SEC, f'the stop took {stop_sec:.2f} s'
    assert {(a.status_code, a.json()['error']['code']) for a in answers} == {
        (422, 'invalid_request')
    }
