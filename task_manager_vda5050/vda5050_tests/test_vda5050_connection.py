"""The vehicle's connection: ONLINE, OFFLINE when stopped, CONNECTIONBROKEN (the last will)
when it vanishes, all retained; an order that goes on while the broker is away, its state
published again on the broker's return; and one whose end the adapter's reader lost."""

import os
import re
import signal

import pytest

from task_manager.client import Subtask, TaskManagerClient
from task_manager.core.bounds import IDS_MAX
from task_manager.core.status import TaskStatus
from task_manager.rclpy_tools.qos import DEEP_QUEUE_DEPTH
from task_manager.testing.gateway import wait_until
from task_manager.testing.harness import RosHarness
from task_manager.testing.lost_events import LONG_LEASE, batch_counter
from task_manager_vda5050.testing import (
    TIMEOUT_SEC,
    AdapterProcess,
    BrokerProcess,
    Master,
    ended,
    latest_state,
    node,
    order,
    photo,
)

pytestmark = pytest.mark.ros
READ_AGAIN = r'task events went missing: reading the \d+ tasks followed again'
MORE_THAN_THE_WRITER_KEEPS = DEEP_QUEUE_DEPTH + 500


def connection_states(master: Master) -> list[str]:
    return [m['connectionState'] for m in master.messages('connection')]


def test_a_stopped_vehicle_says_offline_and_one_that_vanishes_connection_broken(
    master: Master, adapter: AdapterProcess, broker: BrokerProcess
) -> None:
    assert adapter.stop() == 0

    master.wait_for(lambda _: connection_states(master)[-1:] == ['OFFLINE'], 'OFFLINE')
    vanishing = AdapterProcess(broker)
    master.wait_for(lambda _: connection_states(master)[-1:] == ['ONLINE'], 'ONLINE again')
    vanishing.kill()
    master.wait_for(
        lambda _: connection_states(master)[-1:] == ['CONNECTIONBROKEN'], 'CONNECTIONBROKEN'
    )

    late = Master(broker, 'master')  # a master that comes later reads the retained state
    try:
        late.wait_for(
            lambda _: (
                [m['connectionState'] for m in late.messages('connection')] == ['CONNECTIONBROKEN']
            ),
            'the retained CONNECTIONBROKEN',
        )
    finally:
        late.stop()


def test_an_order_goes_on_while_the_broker_is_away_and_state_returns_with_it(
    master: Master, broker: BrokerProcess, demo_robot: TaskManagerClient
) -> None:
    away = order('order-away', node('a', 0, 0.0, 0.0), node('b', 2, 12.0, 0.0))
    master.command('order', order=away)
    latest_state(master, lambda s: s['driving'], 'driving')

    broker.stop()
    (mission,) = ended(demo_robot, 'order-away')  # while the broker is away
    assert mission.status is TaskStatus.DONE
    seen_before = len(master.messages('state'))
    broker.start()

    back = master.wait_for(
        lambda _: (
            len(master.messages('state')) > seen_before
            and master.messages('state')[-1]['lastNodeId'] == 'b'
        ),
        'the state after the return',
    )
    assert back
    state = master.messages('state')[-1]
    assert (state['orderId'], state['nodeStates'], state['driving']) == ('order-away', [], False)


@pytest.mark.parametrize('adapter_env', [LONG_LEASE])
def test_an_order_whose_end_went_missing_is_read_again(
    master: Master, adapter: AdapterProcess, demo_robot: TaskManagerClient, ros: RosHarness
) -> None:
    """The adapter stopped (SIGSTOP) while its order ends and the Task Manager publishes more
    batches of task events than its writer keeps: the ENDED events of the order's tasks are
    among those lost, so once it goes on it reads the tasks it follows again. Before, the
    vehicle stayed driving, its last node the first, its action waiting, for good. (The adapter
    has a 60 s lease here: stopped for longer than its lease, it at times heard nothing more
    from the node at all; docs/faults-and-shutdown.md.)"""
    batches = batch_counter(ros)
    lost = order('order-lost', node('s', 0, 0.0, 0.0), node('f', 2, 8.0, 0.0, photo()))
    master.command('order', order=lost)
    latest_state(master, lambda s: s['driving'], 'driving')  # its events taken
    os.kill(adapter.process.pid, signal.SIGSTOP)
    try:
        (mission,) = ended(demo_robot, 'order-lost')
        assert mission.status is TaskStatus.DONE
        flood, before = [Subtask('system/wait', {'duration': 0.001})] * IDS_MAX, batches()
        while batches() - before < MORE_THAN_THE_WRITER_KEEPS:
            demo_robot.start_mission(flood)[0].result(TIMEOUT_SEC)
    finally:
        os.kill(adapter.process.pid, signal.SIGCONT)

    def told() -> bool:
        # a batch for the adapter, which shows it the gap
        demo_robot.run_task('system/wait', {'duration': 0.001})
        return any(re.search(READ_AGAIN, line) for line in adapter.log_lines)

    wait_until(told, 'the adapter reading its tasks again', TIMEOUT_SEC)
    state = latest_state(master, lambda s: s['lastNodeId'] == 'f', 'f reached')
    assert (state['driving'], state['nodeStates']) == (False, [])
    assert [a['actionStatus'] for a in state['actionStates']] == ['FINISHED']
