"""What the vehicle refuses at its door and how it keeps what it sends within the broker's
limit, through the adapter, the demo robot's Task Manager and a real mosquitto; the master of
test_vda5050_master.py sends (its `raw` command for what it would not send) and watches."""

import json
from typing import Any

import pytest

from task_manager.client import TaskManagerClient
from task_manager.core.bounds import VDA5050_UPDATES_WAITING_MAX
from task_manager_vda5050.testing import (
    AdapterProcess,
    Master,
    errors_of,
    instant,
    instant_state,
    latest_state,
    node,
    order,
    photo,
    processed,
    refs,
    with_header,
)

pytestmark = pytest.mark.ros

HUGE = 600_000
"""Characters of a string that, echoed twice into state, made it larger than the broker's
packet limit (1 MiB): the vehicle was disconnected at each state, for good."""
SMALL_BROKER_BYTES = 16_384


def answers_and_stayed_online(master: Master) -> dict[str, Any]:
    """The vehicle still answers a stateRequest, was never disconnected, and no state it
    sent was large; the state that answered."""
    request = instant('stateRequest')
    master.command('instant', actions=[request])

    instant_state(master, request, 'FINISHED')
    assert [m['connectionState'] for m in master.messages('connection')] == ['ONLINE']
    assert max(len(json.dumps(s)) for s in master.messages('state')) < 64_000
    return latest_state(
        master,
        lambda s: any(
            (a['actionId'], a['actionStatus']) == (request['actionId'], 'FINISHED')
            for a in s['actionStates']
        ),
        'the stateRequest FINISHED',
    )


def test_an_instant_action_of_a_huge_type_is_refused_and_the_vehicle_stays_online(
    master: Master,
) -> None:
    huge = {'actionId': 'huge-type', 'actionType': 'x' * HUGE, 'blockingType': 'HARD'}

    master.command('raw', topic='instantActions', payload=with_header({'actions': [huge]}))

    (error,) = errors_of(master, 'validationError')
    assert refs(error)['field'] == 'actions/0/actionType'
    assert f'is {HUGE} characters; at most 100 allowed' in error['errorDescription']
    answers_and_stayed_online(master)


def test_state_requests_with_huge_descriptions_are_refused_and_the_vehicle_stays_online(
    master: Master,
) -> None:
    for _ in range(2):
        request = {**instant('stateRequest'), 'actionDescription': 'd' * HUGE}
        master.command('instant', actions=[request])

    errors = errors_of(master, 'validationError', 2)

    assert [refs(e)['field'] for e in errors] == ['actions/0/actionDescription'] * 2
    answers_and_stayed_online(master)


@pytest.mark.parametrize('broker', [SMALL_BROKER_BYTES], indirect=True)
def test_a_state_larger_than_the_broker_takes_goes_out_shortened_said_once(
    master: Master, adapter: AdapterProcess
) -> None:
    for number in range(30):  # each ~1 kB in state: 30 kB, over the broker's 16 kB
        request = {**instant('stateRequest'), 'actionDescription': f'{number} ' + 'd' * 900}
        master.command('instant', actions=[request])

    answer = answers_and_stayed_online(master)

    assert [i['infoType'] for i in answer['information']] == ['stateShortened']
    assert len(answer['actionStates']) == 31  # all there, without their descriptions
    assert all('actionDescription' not in a for a in answer['actionStates'])
    said = adapter.wait_for_log('state shortened', 5.0)
    assert [line for line in adapter.log_lines if 'shortened' in line] == [said]


def test_a_message_naming_another_vehicle_is_refused(
    master: Master, demo_robot: TaskManagerClient
) -> None:
    elsewhere = order('order-elsewhere', node('a', 0, 0.0, 0.0))
    pause = instant('startPause')

    master.command('raw', topic='order', payload=with_header(elsewhere, serialNumber='robot2'))
    master.command(
        'raw',
        topic='instantActions',
        payload=with_header({'actions': [pause]}, manufacturer='evil'),
    )

    wrong_serial, wrong_manufacturer = errors_of(master, 'validationError', 2)
    assert (refs(wrong_serial)['topic'], refs(wrong_serial)['field']) == ('order', 'serialNumber')
    assert 'robot2' in wrong_serial['errorDescription']
    assert refs(wrong_manufacturer)['field'] == 'manufacturer'
    state = latest_state(master, lambda s: len(s['errors']) == 2, 'both errors')
    assert (state['orderId'], state['paused']) == ('', False)
    assert demo_robot.task_states(['order-elsewhere']) == []


def test_a_deeply_nested_message_is_refused_in_a_short_log_line(
    master: Master, adapter: AdapterProcess
) -> None:
    deep = '[' * 100_000 + ']' * 100_000

    master.command('raw', topic='order', payload=f'{{"orderId": {deep}}}')

    (error,) = errors_of(master, 'validationError')
    assert 'deeper than 32 levels' in error['errorDescription']
    adapter.wait_for_log('order not acted on', 5.0)
    assert max(len(line) for line in adapter.log_lines) < 2000
    master.command('order', order=order('order-after', node('home', 0, 0.0, 0.0)))
    assert processed(master, 'order-after')['error'] is None


def test_an_action_id_equal_to_a_drive_is_refused_before_anything_starts(
    master: Master, demo_robot: TaskManagerClient
) -> None:
    clash = {**photo(), 'actionId': 'b/2'}  # its task id: order-clash/b/2, the drive's to b
    clashing = order('order-clash', node('a', 0, 0.0, 0.0), node('b', 2, 1.0, 0.0, clash))

    master.command('order', order=clashing)

    (error,) = errors_of(master, 'validationError')  # the library leaves to the action
    assert (refs(error)['orderId'], refs(error)['actionId']) == ('order-clash', 'b/2')
    assert latest_state(master, lambda s: s['errors'], 'the error')['orderId'] == ''
    assert demo_robot.task_states(['order-clash']) == []


def test_no_more_updates_wait_than_the_bound(master: Master) -> None:
    last = node('far', 2, 200.0, 0.0)
    master.command('order', order=order('order-wait', node('home', 0, 0.0, 0.0), last))
    latest_state(master, lambda s: s['driving'], 'driving')

    for update_id in range(1, VDA5050_UPDATES_WAITING_MAX + 2):
        following = node(f'far{update_id}', last['sequenceId'] + 2, 200.0, float(update_id))
        update = {**order('order-wait', last, following), 'orderUpdateId': update_id}
        master.command('raw', topic='order', payload=with_header(update, update_id))
        last = following

    (error,) = errors_of(master, 'orderUpdateError')
    assert refs(error)['orderUpdateId'] == str(VDA5050_UPDATES_WAITING_MAX + 1)
    assert f'at most {VDA5050_UPDATES_WAITING_MAX}' in error['errorDescription']
    state = latest_state(master, lambda s: s['errors'], 'the error')
    assert state['orderUpdateId'] == VDA5050_UPDATES_WAITING_MAX
    cancel = instant('cancelOrder')
    master.command('instant', actions=[cancel])
    instant_state(master, cancel, 'FINISHED')
