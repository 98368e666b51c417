"""The vehicle's connection: ONLINE, OFFLINE when stopped, CONNECTIONBROKEN (the last will)
when it vanishes, all retained; and an order that goes on while the broker is away, its
state published again on the broker's return."""

import pytest

from task_manager.client import TaskManagerClient
from task_manager.core.status import TaskStatus
from task_manager_vda5050.testing import (
    AdapterProcess,
    BrokerProcess,
    Master,
    ended,
    errors_of,
    latest_state,
    node,
    order,
)

pytestmark = pytest.mark.ros


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


def test_an_adapter_started_while_an_earlier_ones_order_runs_cancels_it_and_says_so(
    master: Master, adapter: AdapterProcess, broker: BrokerProcess, demo_robot: TaskManagerClient
) -> None:
    """The adapter killed while its order drives (a crash; or exit 3 and its supervisor): the
    one started after it knows nothing of that order, so it cancels its tasks (the vehicle
    stops) and its state says so, for the master to send the order again."""
    long_leg = order('order-lost', node('a', 0, 0.0, 0.0), node('b', 2, 40.0, 0.0))
    master.command('order', order=long_leg)
    latest_state(master, lambda s: s['driving'], 'driving')
    adapter.kill()
    master.wait_for(
        lambda _: connection_states(master)[-1:] == ['CONNECTIONBROKEN'], 'CONNECTIONBROKEN'
    )

    again = AdapterProcess(broker)
    try:
        (mission,) = ended(demo_robot, 'order-lost')
        (lost,) = errors_of(master, 'orderLost')
        state = master.messages('state')[-1]
    finally:
        assert again.stop() == 0, '\n'.join(again.log_lines)
    assert mission.status is TaskStatus.CANCELED
    assert lost['errorLevel'] == 'WARNING' and 'send the order again' in lost['errorDescription']
    assert (state['orderId'], state['driving']) == ('', False)
