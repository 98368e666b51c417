"""A master control no one here wrote (npm's vda-5050-lib MasterController, VDA 5050 2.0.0)
drives the demo robot through the adapter and its Task Manager, over a real mosquitto: an
order with an action, pause and resume, cancelOrder, factsheetRequest and malformed
messages. Every message the master receives is checked (conftest.check_every_message)."""

import json

import pytest

from task_manager.client import TaskManagerClient
from task_manager.core.status import TaskStatus
from task_manager_vda5050.testing import (
    Master,
    ended,
    instant,
    instant_state,
    latest_state,
    node,
    order,
    photo,
    processed,
)

pytestmark = pytest.mark.ros


def test_the_master_completes_an_order_with_an_action(
    master: Master, demo_robot: TaskManagerClient
) -> None:
    action = photo()
    first, second = node('start', 0, 0.0, 0.0), node('shelf', 2, 2.0, 1.0, action)
    master.command('order', order=order('order-photo', first, second))

    done = processed(master, 'order-photo')

    assert (done['error'], done['byCancelation'], done['active']) == (None, False, False)
    traversed = [e['nodeId'] for e in master.events if e['event'] == 'nodeTraversed']
    assert traversed[-1] == 'shelf'
    finished = master.wait_for(
        lambda e: e['event'] == 'actionState' and e['actionState']['actionStatus'] == 'FINISHED',
        'the photo FINISHED',
    )
    assert json.loads(finished['actionState']['resultDescription'])['success'] is True
    (mission,) = ended(demo_robot, 'order-photo')
    assert (mission.task_name, mission.status) == ('system/mission', TaskStatus.DONE)
    (photo_task,) = ended(demo_robot, f'order-photo/{action["actionId"]}')
    assert (photo_task.task_name, photo_task.mission_id) == ('camera/take_photo', 'order-photo')
    state = latest_state(master, lambda s: s['lastNodeId'] == 'shelf', 'lastNodeId shelf')
    assert state['agvPosition']['x'] == pytest.approx(2.0, abs=0.05)
    assert state['batteryState'] == {'batteryCharge': 80.0, 'charging': False}  # the mapping's


def test_the_master_pauses_and_resumes_an_order(master: Master) -> None:
    master.command(
        'order', order=order('order-far', node('a', 0, 0.0, 0.0), node('far', 2, 40.0, 0.0))
    )
    latest_state(master, lambda s: s['driving'], 'driving')
    pause = instant('startPause')

    master.command('instant', actions=[pause])

    instant_state(master, pause, 'FINISHED')
    paused = latest_state(master, lambda s: s['paused'] and not s['driving'], 'paused')
    assert paused['nodeStates'][-1]['nodeId'] == 'far'
    resume = instant('stopPause')
    master.command('instant', actions=[resume])
    instant_state(master, resume, 'FINISHED')
    latest_state(master, lambda s: not s['paused'] and s['driving'], 'driving again')
    done = processed(master, 'order-far')
    assert (done['error'], done['byCancelation']) == (None, False)


def test_the_master_cancels_a_long_order(master: Master, demo_robot: TaskManagerClient) -> None:
    long_order = order(
        'order-long', node('a', 0, 0.0, 0.0), node('b', 2, -40.0, 0.0), node('c', 4, 0.0, 0.0)
    )
    master.command('order', order=long_order)
    latest_state(master, lambda s: s['driving'], 'driving')
    cancel = instant('cancelOrder')

    master.command('instant', actions=[cancel])

    done = processed(master, 'order-long')
    assert (done['error'], done['byCancelation']) == (None, True)
    instant_state(master, cancel, 'FINISHED')
    (mission,) = ended(demo_robot, 'order-long')
    assert mission.status is TaskStatus.CANCELED
    nothing_left = latest_state(master, lambda s: not s['nodeStates'], 'no node left')
    assert nothing_left['driving'] is False


def test_cancel_order_without_an_order_fails_with_a_warning(master: Master) -> None:
    cancel = instant('cancelOrder')

    master.command('instant', actions=[cancel])

    failed = instant_state(master, cancel, 'FAILED')
    assert (failed['error']['errorType'], failed['error']['errorLevel']) == (
        'noOrderToCancel',
        'WARNING',
    )


def test_the_master_gets_the_factsheet(master: Master) -> None:
    request = instant('factsheetRequest')

    master.command('instant', actions=[request])

    instant_state(master, request, 'FINISHED')
    sheet = master.wait_for(
        lambda e: e['event'] == 'message' and e['topic'] == 'factsheet', 'a factsheet'
    )['object']
    actions = {a['actionType']: a for a in sheet['protocolFeatures']['agvActions']}
    assert actions['take_photo']['actionScopes'] == ['INSTANT', 'NODE', 'EDGE']
    assert actions['take_photo']['actionDescription'].endswith('Blocking types: NONE, SOFT, HARD.')
    assert actions['take_photo']['actionParameters'] == [
        {'key': 'camera', 'valueDataType': 'STRING', 'isOptional': True}
    ]
    assert {'startPause', 'stopPause', 'cancelOrder', 'stateRequest', 'factsheetRequest'} <= set(
        actions
    )


def test_a_malformed_order_is_reported_and_the_vehicle_still_takes_orders(master: Master) -> None:
    malformed = {**order('order-bad', node('a', 0, 0.0, 0.0)), 'headerId': 1,
                 'timestamp': '2024-01-01T00:00:00.00Z', 'version': '2.0.0',
                 'manufacturer': 'acme', 'serialNumber': 'robot1'}  # fmt: skip
    malformed['nodes'][0]['sequenceId'] = 'zero'

    master.command('raw', topic='order', payload=json.dumps(malformed))
    master.command('raw', topic='instantActions', payload='not json')

    state = latest_state(
        master,
        lambda s: len([e for e in s['errors'] if e['errorType'] == 'validationError']) == 2,
        'two validation errors',
    )
    order_error, text_error = [e for e in state['errors'] if e['errorType'] == 'validationError']
    references = {r['referenceKey']: r['referenceValue'] for r in order_error['errorReferences']}
    assert references == {'topic': 'order', 'field': 'nodes/0/sequenceId'}
    assert 'not valid JSON' in text_error['errorDescription']
    assert state['orderId'] == ''
    master.command('order', order=order('order-good', node('home', 0, 0.0, 0.0)))
    done = processed(master, 'order-good')
    assert done['error'] is None
