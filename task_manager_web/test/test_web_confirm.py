"""POST /api/tasks/{task_id}/confirm (issue 30, item 2): an operator answers a waiting
system/confirm over HTTP, against a real gateway process and a real Task Manager node; the
caller's token names who answered."""

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check, wait_until
from task_manager_web.testing import GatewayProcess

pytestmark = pytest.mark.ros

OPERATOR_TOKEN = 'operator-token-0123456789'
VIEWER_TOKEN = 'viewer-token-0123456789'


@pytest.fixture
def web(robot: Robot, tmp_path: Path) -> Iterator[Callable[[str | None], httpx.Client]]:
    """HTTP clients of one gateway whose token file has operator alice and viewer victor:
    `web(token)` (None: no token), once the gateway reaches the node."""
    token_file = tmp_path / 'tokens'
    token_file.write_text(f'operator {OPERATOR_TOKEN} alice\nviewer {VIEWER_TOKEN} victor\n')
    gateway = GatewayProcess(token_file)
    clients: list[httpx.Client] = []

    def client(token: str | None) -> httpx.Client:
        headers = {'Authorization': f'Bearer {token}'} if token else {}
        clients.append(httpx.Client(base_url=gateway.url, headers=headers, timeout=TIMEOUT_SEC))
        return clients[-1]

    alice = client(OPERATOR_TOKEN)
    wait_until(lambda: alice.get('/api/health').json()['connected'], 'gateway connected')
    yield client
    for each in clients:
        each.close()
    assert gateway.stop() == 0, '\n'.join(gateway.log_lines)


def start_waiting(http: httpx.Client, task_id: str, prompt: str = 'Load the tray') -> None:
    """Start system/confirm `task_id` and wait until the gateway shows its prompt."""
    body = {'task_name': 'system/confirm', 'task_data': {'prompt': prompt}, 'task_id': task_id}
    started = http.post('/api/tasks/start', json=body)
    assert started.status_code == 202, started.text
    wait_until(
        lambda: (http.get(f'/api/tasks/{task_id}').json().get('feedback') or {}).get('prompt'),
        f'{task_id} waiting',
    )


def ended(http: httpx.Client, task_id: str) -> dict[str, Any]:
    """The task once ended, as GET /api/tasks/{task_id} shows it."""
    task: dict[str, Any] = check(
        wait_until(
            lambda: (
                (task := http.get(f'/api/tasks/{task_id}').json())['status']
                in ('DONE', 'ERROR', 'CANCELED')
                and task
            ),
            f'{task_id} ended',
        ),
        'task',
    )
    return task


def test_an_operator_confirms_and_the_task_keeps_who_did(
    web: Callable[[str | None], httpx.Client],
) -> None:
    alice = web(OPERATOR_TOKEN)
    start_waiting(alice, 'tray/load')
    waiting = check(alice.get('/api/tasks/tray/load').json(), 'task')

    response = alice.post('/api/tasks/tray/load/confirm', json={'comment': 'tray loaded'})

    assert (waiting['status'], waiting['feedback']['prompt']) == ('IN_PROGRESS', 'Load the tray')
    assert response.status_code == 200, response.text
    assert check(response.json(), 'confirmed') == {
        'task_id': 'tray/load',
        'outcome': 'confirmed',
        'by': 'WEB:alice',
        'comment': 'tray loaded',
    }
    task = ended(alice, 'tray/load')
    assert (task['status'], task['source']) == ('DONE', 'WEB:alice')
    assert task['result'] == {
        'confirmed': True,
        'by': 'WEB:alice',
        'comment': 'tray loaded',
        'outcome': 'confirmed',
    }


def test_an_operator_rejects_and_the_task_ends_error_rejected(
    web: Callable[[str | None], httpx.Client],
) -> None:
    alice = web(OPERATOR_TOKEN)
    start_waiting(alice, 'path-clear', 'Is the path clear?')

    response = alice.post('/api/tasks/path-clear/confirm', json={'reject': True})

    assert response.status_code == 200, response.text
    assert check(response.json(), 'confirmed')['outcome'] == 'rejected'
    task = ended(alice, 'path-clear')
    assert (task['status'], task['error_code']) == ('ERROR', 'rejected')
    assert task['result']['by'] == 'WEB:alice'


def test_without_token_or_role_nothing_is_answered(
    web: Callable[[str | None], httpx.Client],
) -> None:
    alice = web(OPERATOR_TOKEN)
    start_waiting(alice, 'guarded')

    nobody = web(None).post('/api/tasks/guarded/confirm', json={})
    viewer = web(VIEWER_TOKEN).post('/api/tasks/guarded/confirm', json={})

    assert nobody.status_code == 401
    assert check(nobody.json(), 'error')['error']['code'] == 'unauthorized'
    assert viewer.status_code == 403
    assert check(viewer.json(), 'error')['error']['message'] == (
        'POST /api/tasks/guarded/confirm needs role operator; this token is viewer'
    )
    assert alice.get('/api/tasks/guarded').json()['status'] == 'IN_PROGRESS'  # still waiting
    assert alice.post('/api/tasks/guarded/confirm', json={}).status_code == 200


def test_an_unknown_id_is_404_and_a_task_that_is_no_waiting_confirmation_409(
    robot: Robot, web: Callable[[str | None], httpx.Client]
) -> None:
    alice = web(OPERATOR_TOKEN)
    fib = {'task_name': 'fib', 'task_data': {'order': 1}, 'task_id': 'fib-1'}
    started = alice.post('/api/tasks/start', json=fib)
    assert started.status_code == 202, started.text
    (goal,) = robot.fib.wait_for_goals(1, TIMEOUT_SEC)

    unknown = alice.post('/api/tasks/ghost/confirm', json={})
    refused_id = alice.post('/api/tasks/gh%E2%80%AEost/confirm', json={})
    not_a_confirm = alice.post('/api/tasks/fib-1/confirm', json={})
    goal.succeed()
    ended(alice, 'fib-1')
    ended_fib = alice.post('/api/tasks/fib-1/confirm', json={})

    for response in (unknown, refused_id):
        error = check(response.json(), 'error')['error']
        assert (response.status_code, error['code']) == (404, 'unknown_task_id'), response.text
    assert "no task 'ghost'" in check(unknown.json(), 'error')['error']['message']
    for response in (not_a_confirm, ended_fib):
        error = check(response.json(), 'error')['error']
        assert (response.status_code, error['code']) == (409, 'not_waiting'), response.text
        assert "task 'fib-1' is a fib task, not system/confirm" in error['message']


@pytest.mark.parametrize(
    ('body', 'field'),
    [
        ({'reject': 'yes'}, 'reject'),
        ({'comment': 'line\nforged'}, 'comment'),
        ({'comment': 'x' * 1001}, 'comment'),
        ({'by': 'someone else'}, 'by'),
    ],
)
def test_a_wrong_body_is_422_naming_its_field_and_answers_nothing(
    web: Callable[[str | None], httpx.Client], body: dict[str, Any], field: str
) -> None:
    alice = web(OPERATOR_TOKEN)
    start_waiting(alice, 'strict')

    response = alice.post('/api/tasks/strict/confirm', json=body)

    error = check(response.json(), 'error')['error']
    assert (response.status_code, error['code'], error['field']) == (422, 'invalid_request', field)
    assert alice.get('/api/tasks/strict').json()['status'] == 'IN_PROGRESS'
