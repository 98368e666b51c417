"""Fixtures of the gateway tests: a real Task Manager node and a real gateway, as users run them.

The node serves `fib` (a scripted Fibonacci action server in the test process, reentrant,
cancelled by system/stop) and `instant` (a SetBool service that answers at once).
"""

from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import pytest
from std_srvs.srv import SetBool
from test_msgs.action import Fibonacci

from task_manager.testing.harness import RosHarness
from task_manager.testing.process import NodeProcess, action_task, service_task, write_params_file
from task_manager.testing.servers import ScriptedActionServer, ScriptedService
from task_manager_web.testing import TIMEOUT_SEC, GatewayProcess, Robot, wait_until

START_TIMEOUT_SEC = 20.0
SERVER_WAIT_TIMEOUT_SEC = 10.0


@pytest.fixture
def start_robot(ros: RosHarness, tmp_path: Path) -> Iterator[Callable[[], Robot]]:
    """Start the Task Manager (callable again after `robot.process.stop()`)."""
    prefix = f'/w{abs(hash(tmp_path)) % 10**8}'
    fib = ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/fib')
    instant = ScriptedService(
        ros.node, SetBool, f'{prefix}/instant', on_call=lambda call: call.respond(success=True)
    )
    tasks = {
        'fib': action_task('fib', f'{prefix}/fib', reentrant=True, cancel_on_stop=True),
        'instant': service_task('instant', f'{prefix}/instant', reentrant=True),
    }
    params = write_params_file(
        tmp_path / 'params.yaml',
        {
            'tasks': list(tasks),
            **tasks,
            'history_path': str(tmp_path / 'history.sqlite'),
            # the node must discover this process's servers: 1 s (the default) is not always
            # enough with the other test process busy on the same 2 cores
            'server_wait_timeout': SERVER_WAIT_TIMEOUT_SEC,
        },
    )
    processes: list[NodeProcess] = []

    def start() -> Robot:
        process = NodeProcess(params)
        processes.append(process)
        process.wait_for_log(r'Task Manager ready', START_TIMEOUT_SEC)
        return Robot(process, fib, instant)

    yield start
    for process in processes:
        process.stop()
    fib.destroy()
    instant.destroy()


@pytest.fixture
def robot(start_robot: Callable[[], Robot]) -> Robot:
    return start_robot()


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
