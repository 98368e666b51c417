"""The gateway stops on SIGINT or SIGTERM from its first line on, whatever it is doing, and
exits 3 when, held up, it no longer hears its node."""

import asyncio
import signal
from collections.abc import Callable, Iterator
from typing import Any

import httpx
import pytest

from task_manager.process_setup import EXIT_NODE_UNHEARD
from task_manager.testing.gateway import TIMEOUT_SEC, Robot
from task_manager.testing.process import STOP_TIMEOUT_SEC, held_up_with_its_node
from task_manager_web.http_server import Server, listen, server_config, stopped_by_signals
from task_manager_web.testing import GatewayProcess


async def _app(scope: dict[str, Any], receive: Any, send: Any) -> None:
    """An ASGI app that has no lifespan (uvicorn then goes on without one)."""
    raise RuntimeError('no lifespan here')


@pytest.fixture
def sigint_default() -> Iterator[None]:
    before = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


@pytest.mark.usefixtures('sigint_default')
@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
def test_a_signal_before_the_server_starts_stops_it_once_started(signum: int) -> None:
    """Before `stopped_by_signals`, a SIGINT here would be a KeyboardInterrupt in the test, and
    uvicorn's own handler (put in place by `serve`) would have been too late for it."""
    stopping: list[bool] = []
    server = Server(server_config(_app), lambda: stopping.append(server.should_exit))
    listener = listen('test', '127.0.0.1', 0)
    with stopped_by_signals(server):
        signal.raise_signal(signum)
        asyncio.run(asyncio.wait_for(server.serve(sockets=[listener]), STOP_TIMEOUT_SEC))
        handler_within = signal.getsignal(signum)

    assert server.should_exit
    assert not server.force_exit
    assert server.started  # it started, then stopped at once: no main loop
    assert stopping == [True]  # told once, as it began to stop
    assert handler_within is not signal.default_int_handler  # serve took nothing over
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # put back


@pytest.mark.usefixtures('sigint_default')
def test_a_second_sigint_asks_for_a_stop_without_waiting() -> None:
    server = Server(server_config(_app), lambda: None)
    with stopped_by_signals(server):
        signal.raise_signal(signal.SIGTERM)
        assert not server.force_exit
        signal.raise_signal(signal.SIGINT)
    assert server.force_exit


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGINT, signal.SIGTERM])
def test_the_gateway_stops_cleanly_on_a_signal_right_after_its_first_line(
    start_gateway: Callable[..., GatewayProcess], signum: int
) -> None:
    gateway = start_gateway()  # returns once the dashboard line is out

    gateway.process.send_signal(signum)

    assert gateway.wait_exit(STOP_TIMEOUT_SEC) == 0, '\n'.join(gateway.log_lines)


def test_a_gateway_held_up_that_no_longer_hears_its_node_exits_3(
    robot: Robot, gateway: GatewayProcess, http: httpx.Client
) -> None:
    """Stopped (SIGSTOP) with its node past its client's check's hold-up, then let go while
    the node stays stopped: it hears nothing, says so and exits 3, for its supervisor."""
    gateway.exit_code = EXIT_NODE_UNHEARD
    assert held_up_with_its_node(gateway, robot.process, TIMEOUT_SEC) == EXIT_NODE_UNHEARD
    gateway.wait_for_log('has not heard the Task Manager again within 10 s', TIMEOUT_SEC)
