"""A history page is bounded in bytes (--max-history-bytes) with a real node and gateway: one
that would be larger is refused with `reply_too_large`, saying how many tasks fit, and that
many are then answered, in JSON as in CSV."""

import re
from collections.abc import Callable, Iterator

import httpx
import pytest

from task_manager.client import TaskManagerClient
from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check
from task_manager_web.testing import GatewayProcess, gateway_client

pytestmark = pytest.mark.ros
MAX_BYTES = 6000
ENDED = 40


@pytest.fixture
def small_pages(
    robot: Robot, start_gateway: Callable[..., GatewayProcess]
) -> Iterator[httpx.Client]:
    """A gateway that answers history pages up to MAX_BYTES, the node's history holding
    ENDED tasks (of about 400 bytes each in JSON)."""
    with TaskManagerClient('history_pages', timeout_sec=TIMEOUT_SEC) as client:
        client.wait_until_available()
        for n in range(ENDED):
            client.run_task('instant', {'data': True}, task_id=f'page-{n:02d}')
    with gateway_client(start_gateway('--max-history-bytes', str(MAX_BYTES))) as http:
        yield http


def fitting(refused: httpx.Response, asked: int = ENDED) -> int:
    """How many tasks a refusal of `asked` says fit."""
    assert refused.status_code == 422, refused.text
    error = refused.json()['error']
    assert (error['code'], error['field']) == ('reply_too_large', 'limit')
    assert f'({asked} tasks) would be ' in error['message']
    assert f'at most {MAX_BYTES} are answered' in error['message']
    match = re.search(r'the first (\d+) of these fit', error['message'])
    assert match is not None, error['message']
    return int(match[1])


@pytest.mark.parametrize('page_format', ['json', 'csv'])
def test_a_page_over_the_bound_is_refused_saying_how_many_fit(
    small_pages: httpx.Client, page_format: str
) -> None:
    query: dict[str, str | int] = {'limit': ENDED, 'format': page_format, 'oldest_first': 'true'}

    fit = fitting(small_pages.get('/api/history', params=query))
    page = small_pages.get('/api/history', params={**query, 'limit': fit})
    over = small_pages.get('/api/history', params={**query, 'limit': fit + 1})

    assert 0 < fit < ENDED
    assert page.status_code == 200 and len(page.content) <= MAX_BYTES
    assert fitting(over, fit + 1) == fit
    if page_format == 'json':
        tasks = [check(task, 'task') for task in page.json()]
        assert [t['task_id'] for t in tasks] == [f'page-{n:02d}' for n in range(fit)]
        after = tasks[-1]['sequence']
        rest = small_pages.get(
            '/api/history', params={**query, 'limit': fit, 'after_sequence': after}
        )
        assert rest.json()[0]['task_id'] == f'page-{fit:02d}'
    else:
        assert page.headers['content-type'].startswith('text/csv')
        assert page.text.count('\r\n') == fit + 1  # and the header
