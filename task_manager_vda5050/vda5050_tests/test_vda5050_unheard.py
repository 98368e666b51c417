"""The adapter held up past the DDS lease that no longer hears its Task Manager: it says so,
publishes OFFLINE and exits 3, for its supervisor to start a process that hears the node.
The module's own Task Manager (the demo's tasks, no robot: nothing runs), which the test stops
with the adapter."""

import os
import signal
from collections.abc import Iterator

import pytest

from task_manager.process_setup import EXIT_NODE_UNHEARD
from task_manager.testing.process import NodeProcess, held_up_with_its_node
from task_manager_demo.run_demo import default_params_file
from task_manager_demo.testing import START_TIMEOUT_SEC
from task_manager_vda5050.broker import MASTER_USER
from task_manager_vda5050.testing import TIMEOUT_SEC, AdapterProcess, BrokerProcess, Master

pytestmark = pytest.mark.ros


@pytest.fixture
def task_manager() -> Iterator[NodeProcess]:
    task_manager = NodeProcess(default_params_file())
    try:
        task_manager.wait_for_log(r'Task Manager ready', START_TIMEOUT_SEC)
        yield task_manager
    finally:
        assert task_manager.stop() == 0, '\n'.join(task_manager.log_lines)


def _connection_states(master: Master) -> list[str]:
    return [m['connectionState'] for m in master.messages('connection')]


def test_an_adapter_held_up_that_no_longer_hears_its_node_says_offline_and_exits_3(
    task_manager: NodeProcess, broker: BrokerProcess
) -> None:
    adapter = AdapterProcess(broker)
    master = Master(broker, MASTER_USER)
    try:
        master.wait_for(lambda _: _connection_states(master)[-1:] == ['ONLINE'], 'ONLINE')
        code = held_up_with_its_node(adapter, task_manager, TIMEOUT_SEC)
        assert code == EXIT_NODE_UNHEARD
        adapter.wait_for_log('has not heard the Task Manager again within 10 s', TIMEOUT_SEC)
        master.wait_for(lambda _: _connection_states(master)[-1:] == ['OFFLINE'], 'OFFLINE')
    finally:
        master.stop()
        if adapter.process.poll() is None:
            os.kill(adapter.process.pid, signal.SIGCONT)
            adapter.stop()
