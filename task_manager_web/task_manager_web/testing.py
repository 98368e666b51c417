"""Helpers of the gateway's tests and benchmarks: the gateway run as users do."""

import contextlib
import re
import sys
from collections.abc import Iterator
from pathlib import Path

import httpx

from task_manager.testing.gateway import TIMEOUT_SEC, wait_until
from task_manager.testing.process import NodeProcess
from task_manager_web.tokens import Role, read_token_file

GATEWAY_EXECUTABLE = str(Path(sys.executable).with_name('task-manager-web'))
DASHBOARD_LINE = r'dashboard: (?P<url>http://[^/\s]+)/'
START_TIMEOUT_SEC = 20.0


class GatewayProcess(NodeProcess):
    """`task-manager-web --port 0 --token-file F [args]`; its URL once it listens, and the
    first admin token of F ('' for none)."""

    def __init__(self, token_file: Path, *args: str) -> None:
        super().__init__(
            None,
            command=[GATEWAY_EXECUTABLE, '--port', '0', '--token-file', str(token_file), *args],
        )
        match = re.search(DASHBOARD_LINE, self.wait_for_log(DASHBOARD_LINE, START_TIMEOUT_SEC))
        assert match is not None
        self.url = match['url']
        admins = [t.secret for t in read_token_file(token_file) if t.role is Role.ADMIN]
        self.token = admins[0] if admins else ''


@contextlib.contextmanager
def gateway_client(gateway: GatewayProcess) -> Iterator[httpx.Client]:
    """An HTTP client of the gateway, with its admin token, once the gateway reaches the node."""
    with httpx.Client(
        base_url=gateway.url,
        headers={'Authorization': f'Bearer {gateway.token}'},
        timeout=TIMEOUT_SEC,
    ) as client:
        wait_until(lambda: client.get('/api/health').json()['connected'], 'gateway connected')
        yield client
