"""Fixtures of the gateway tests: a real Task Manager node and a real gateway, as users run them.

The node serves `fib` (a scripted Fibonacci action server in the test process, reentrant,
cancelled by system/stop) and `instant` (a SetBool service that answers at once).
"""

from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import pytest

from task_manager.testing.gateway import TIMEOUT_SEC, Robot, wait_until
from task_manager_web.testing import GatewayProcess


@pytest.fixture
def start_gateway(tmp_path: Path) -> Iterator[Callable[..., GatewayProcess]]:
    gateways: list[GatewayProcess] = []
    token_file = tmp_path / 'token'
    token_file.write_text('test-token-1234\n')

    def start(*args: str) -> GatewayProcess:
        gateway = GatewayProcess(token_file, *args)
        gateways.append(gateway)
        return gateway

    yield start
    for gateway in gateways:
        assert gateway.stop() == 0, '\n'.join(gateway.log_lines)


@pytest.fixture
def gateway(start_gateway: Callable[..., GatewayProcess]) -> GatewayProcess:
    return start_gateway()


@pytest.fixture
def http(robot: Robot, gateway: GatewayProcess) -> Iterator[httpx.Client]:
    """An HTTP client of the gateway, with its token, once the gateway reaches the node."""
    with httpx.Client(
        base_url=gateway.url,
        headers={'Authorization': f'Bearer {gateway.token}'},
        timeout=TIMEOUT_SEC,
    ) as client:
        wait_until(lambda: client.get('/api/health').json()['connected'], 'gateway connected')
        yield client
