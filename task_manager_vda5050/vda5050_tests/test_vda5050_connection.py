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
