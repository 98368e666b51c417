"""Helpers of the gateway's tests and benchmarks: the gateway run as users do."""

import contextlib
import re
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import httpx

from task_manager.testing.gateway import TIMEOUT_SEC, wait_until
from task_manager.testing.process import TEST_NICENESS, NodeProcess, nice_option
from task_manager_web.doors.tokens import Role, read_token_file

if TYPE_CHECKING:  # the dashboard's tests only: the bench runs gateways without a browser
    from playwright.sync_api import APIResponse, Page, Route

GATEWAY_EXECUTABLE = str(Path(sys.executable).with_name('task-manager-web'))
DASHBOARD_LINE = r'dashboard: (?P<url>http://[^/\s]+)/'
START_TIMEOUT_SEC = 20.0


class GatewayProcess(NodeProcess):
    """`task-manager-web --port 0 --token-file F [--nice N] [args]`; its URL once it listens,
    and the first admin token of F ('' for none). `nice`: None for the gateway's default."""

    def __init__(self, token_file: Path, *args: str, nice: int | None = TEST_NICENESS) -> None:
        command = [GATEWAY_EXECUTABLE, '--port', '0', '--token-file', str(token_file)]
        super().__init__(None, command=[*command, *nice_option(nice), *args])
        self.exit_code = 0
        """The code it must end with (a test that makes it exit otherwise says so)."""
        match = re.search(DASHBOARD_LINE, self.wait_for_log(DASHBOARD_LINE, START_TIMEOUT_SEC))
        assert match is not None
        self.url = match['url']
        admins = [t.secret for t in read_token_file(token_file) if t.role is Role.ADMIN]
        self.token = admins[0] if admins else ''


@contextlib.contextmanager
def gateway_client(gateway: GatewayProcess) -> Iterator[httpx.Client]:
    """An HTTP client of the gateway, with its admin token, once the gateway reaches the node and
    hears its events (what ends before is in no event stream and no metric)."""
    with httpx.Client(
        base_url=gateway.url,
        headers={'Authorization': f'Bearer {gateway.token}'},
        timeout=TIMEOUT_SEC,
    ) as client:
        wait_until(lambda: _reaches_the_node(client), 'gateway connected, events included')
        yield client


def _reaches_the_node(client: httpx.Client) -> bool:
    health = client.get('/api/health').json()
    return bool(health['connected'] and health['events'])


class HeldRead:
    """The dashboard's first read of a URL, held unanswered until the test answers it."""

    def __init__(self, page: 'Page', route: 'Route') -> None:
        self.page = page
        self.route = route

    def fetch(self) -> 'APIResponse':
        """What the gateway answers now."""
        return self.route.fetch()

    def answer(self, answer: 'APIResponse') -> None:
        """Answers the read with `answer`; returns once the page's script has had it (its body
        read, then a turn of the page's event loop)."""
        with self.page.expect_response(self.route.request.url) as response:
            self.route.fulfill(response=answer)
        response.value.finished()
        self.page.evaluate('() => new Promise((resolve) => setTimeout(resolve, 0))')
