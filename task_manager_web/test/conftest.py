"""Fixtures of the gateway tests: a real Task Manager node and a real gateway, as users run them.

The node serves `fib` (a scripted Fibonacci action server in the test process, reentrant,
cancelled by system/stop) and `instant` (a SetBool service that answers at once). The
dashboard's tests drive Debian's headless Chromium at /usr/bin/chromium with Playwright, which
never downloads a browser.
"""

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest
from playwright.sync_api import Page, Route, expect

from task_manager.testing.gateway import TIMEOUT_SEC, Robot, ScriptedRobot, SharedBaseRobot
from task_manager.testing.harness import RosHarness
from task_manager.testing.process import TEST_NICENESS
from task_manager_web.doors_testing import blank_page as blank_page
from task_manager_web.doors_testing import browser as browser
from task_manager_web.testing import GatewayProcess, HeldRead, gateway_client


def _token_file(folder: Path) -> Path:
    """The gateways' token file here: one admin token."""
    token_file = folder / 'token'
    token_file.write_text('test-token-0123456789\n')
    return token_file


@pytest.fixture
def start_gateway(tmp_path: Path) -> Iterator[Callable[..., GatewayProcess]]:
    gateways: list[GatewayProcess] = []
    token_file = _token_file(tmp_path)

    def start(*args: str, nice: int | None = TEST_NICENESS) -> GatewayProcess:
        gateway = GatewayProcess(token_file, *args, nice=nice)
        gateways.append(gateway)
        return gateway

    yield start
    for gateway in gateways:
        assert gateway.stop() == gateway.exit_code, '\n'.join(gateway.log_lines)


@pytest.fixture
def gateway(start_gateway: Callable[..., GatewayProcess]) -> GatewayProcess:
    return start_gateway()


# Shared by the tests of a class, for tests that leave nothing running: a node and a gateway
# cost ~1.6 s of CPU to start, for each test otherwise.


@pytest.fixture(scope='class')
def class_ros(ros_context: None, request: pytest.FixtureRequest) -> Iterator[RosHarness]:
    """As `ros`, for the tests of a class."""
    harness = RosHarness(f'test_{abs(hash(request.node.nodeid)) % 10**8}')
    yield harness
    harness.close()


@pytest.fixture(scope='class')
def class_robot(class_ros: RosHarness, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Robot]:
    """As `robot`, for the tests of a class."""
    scripted = ScriptedRobot(class_ros, tmp_path_factory.mktemp('robot'))
    yield scripted.start()
    scripted.close()


@pytest.fixture(scope='class')
def class_base(
    class_ros: RosHarness, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[SharedBaseRobot]:
    """As `base`, for the tests of a class."""
    robot = SharedBaseRobot(class_ros, tmp_path_factory.mktemp('base'))
    yield robot
    robot.close()


@contextmanager
def _shared_gateway_client(folder: Path) -> Iterator[httpx.Client]:
    gateway = GatewayProcess(_token_file(folder))
    with gateway_client(gateway) as client:
        yield client
    assert gateway.stop() == 0, '\n'.join(gateway.log_lines)


@pytest.fixture(scope='class')
def class_http(
    class_robot: Robot, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[httpx.Client]:
    """As `http`, one gateway of `class_robot` for the tests of a class."""
    with _shared_gateway_client(tmp_path_factory.mktemp('gateway')) as client:
        yield client


@pytest.fixture(scope='class')
def class_base_http(
    class_base: SharedBaseRobot, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[httpx.Client]:
    """As `http` with `base`, one gateway of `class_base` for the tests of a class."""
    with _shared_gateway_client(tmp_path_factory.mktemp('gateway')) as client:
        yield client


@pytest.fixture
def http(robot: Robot, gateway: GatewayProcess) -> Iterator[httpx.Client]:
    """An HTTP client of the gateway, with its token, once the gateway reaches the node."""
    with gateway_client(gateway) as client:
        yield client


@pytest.fixture
def base(ros: RosHarness, tmp_path: Path) -> Iterator[SharedBaseRobot]:
    """A Task Manager whose `drive` and `dock` both hold `base` (scripted servers here)."""
    robot = SharedBaseRobot(ros, tmp_path)
    yield robot
    robot.close()


@pytest.fixture
def page(blank_page: Page, robot: Robot, gateway: GatewayProcess) -> Page:
    """The dashboard, opened with the link the gateway printed, once it shows 'connected'."""
    blank_page.goto(f'{gateway.url}/?token={gateway.token}')
    expect(blank_page.locator('#connection')).to_have_text('connected')
    return blank_page


@pytest.fixture
def api(gateway: GatewayProcess) -> Iterator[httpx.Client]:
    """An HTTP client of the gateway, with its token (the dashboard's tests' other door)."""
    headers = {'Authorization': f'Bearer {gateway.token}'}
    with httpx.Client(base_url=gateway.url, headers=headers, timeout=TIMEOUT_SEC) as client:
        yield client


@pytest.fixture
def open_holding_first_read(
    blank_page: Page, robot: Robot, gateway: GatewayProcess
) -> Callable[[str], HeldRead]:
    """Opens the dashboard as `page` does, its first read of `url` (a glob) held unanswered.
    Later reads go through (the route stays: unrouted, a held request would be let go)."""

    def open_page(url: str) -> HeldRead:
        held: list[Route] = []

        def hold_first(route: Route) -> None:
            if held:
                route.continue_()
            else:
                held.append(route)

        blank_page.route(url, hold_first)
        with blank_page.expect_request(url):
            blank_page.goto(f'{gateway.url}/?token={gateway.token}')
        blank_page.evaluate('0')  # a round trip: the route, sent before its answer, is taken
        (read,) = held
        return HeldRead(blank_page, read)

    return open_page
