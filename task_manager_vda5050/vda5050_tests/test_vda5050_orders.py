"""Order updates, rejected orders and the 2.0.0 spelling of instant actions, through the
adapter, the demo robot's Task Manager and a real mosquitto; the master of
test_vda5050_master.py sends and watches (its `raw` command for what it would not send)."""

import itertools
from typing import Any

import pytest

from task_manager.client import TaskManagerClient
from task_manager.core.status import TaskStatus
from task_manager_vda5050.testing import (
    Master,
    edge,
    ended,
    errors_of,
    latest_state,
    node,
    order,
    photo,
    processed,
    refs,
    with_header,
)

pytestmark = pytest.mark.ros


def horizon(document: dict[str, Any], *nodes: dict[str, Any]) -> dict[str, Any]:
    """`document` with `nodes` added after its last node, unreleased."""
    last = document['nodes'][-1]
    unreleased = [{**n, 'released': False} for n in nodes]
    pairs = itertools.pairwise([last, *unreleased])
    edges = [{**edge(a, b), 'released': False} for a, b in pairs]
    return {
        **document,
        'nodes': [*document['nodes'], *unreleased],
        'edges': [*document['edges'], *edges],
    }


def test_an_update_extends_the_running_order_from_its_last_base_node(
    master: Master, demo_robot: TaskManagerClient
) -> None:
    start, middle, end = node('s', 0, 0.0, 0.0), node('m', 2, 3.0, 0.0), node('e', 4, 3.0, 3.0)
    first = horizon(order('order-up', start, middle), end)
    master.command('order', order=first)

    stopped = latest_state(master, lambda s: s['lastNodeId'] == 'm' and not s['driving'], 'at m')
    assert [(n['nodeId'], n['released']) for n in stopped['nodeStates']] == [('e', False)]
    assert [(e['edgeId'], e['released']) for e in stopped['edgeStates']] == [('m-e', False)]
    update = {**order('order-up', middle, end), 'orderUpdateId': 1}
    master.command('order', order=update)

    done = master.wait_for(
        lambda e: e['event'] == 'orderProcessed' and e['orderUpdateId'] == 1, 'update 1 processed'
    )
    assert (done['error'], done['active']) == (None, False)
    at_end = latest_state(master, lambda s: s['lastNodeId'] == 'e', 'at e')
    assert (at_end['orderId'], at_end['orderUpdateId'], at_end['lastNodeSequenceId']) == (
        'order-up',
        1,
        4,
    )
    base, extension = ended(demo_robot, 'order-up', 'order-up/update/1')
    assert (base.status, extension.status) == (TaskStatus.DONE, TaskStatus.DONE)
    (drive,) = ended(demo_robot, 'order-up/e/4')
    assert drive.mission_id == 'order-up/update/1'


def test_a_stale_or_disconnected_update_is_rejected(master: Master) -> None:
    start, middle = node('s', 0, 0.0, 0.0), node('m', 2, 1.0, 0.0)
    master.command('order', order={**order('order-st', start, middle), 'orderUpdateId': 3})
    processed(master, 'order-st')

    stale = {**order('order-st', middle, node('x', 4, 2.0, 0.0)), 'orderUpdateId': 2}
    master.command('raw', topic='order', payload=with_header(stale))
    elsewhere = {**order('order-st', node('s', 0, 0.0, 0.0)), 'orderUpdateId': 4}
    master.command('raw', topic='order', payload=with_header(elsewhere, 2))

    older, off_base = errors_of(master, 'orderUpdateError', 2)
    assert refs(older)['orderUpdateId'] == '2'
    assert refs(off_base)['nodeId'] == 's'
    state = latest_state(master, lambda s: len(s['errors']) == 2, 'both errors')
    assert (state['orderUpdateId'], state['lastNodeId']) == (3, 'm')


def test_an_order_with_an_unmapped_action_is_rejected_up_front(
    master: Master, demo_robot: TaskManagerClient
) -> None:
    dance = {'actionId': 'dance-1', 'actionType': 'dance', 'blockingType': 'HARD'}
    rejected = order('order-dance', node('s', 0, 0.0, 0.0), node('m', 2, 5.0, 0.0, dance))

    master.command('order', order=rejected)

    done = processed(master, 'order-dance')
    assert done['error']['errorType'] == 'orderError'
    assert refs(done['error'])['actionId'] == 'dance-1'
    assert demo_robot.task_states(['order-dance']) == []
    assert latest_state(master, lambda s: True, 'a state')['orderId'] == ''


def test_a_node_without_a_position_is_no_route(master: Master) -> None:
    nowhere = {**node('n', 2, 0.0, 0.0)}
    del nowhere['nodePosition']
    master.command(
        'raw',
        topic='order',
        payload=with_header(order('order-nr', node('s', 0, 0.0, 0.0), nowhere)),
    )

    (error,) = errors_of(master, 'noRouteError')

    assert refs(error)['nodeId'] == 'n'


def test_a_none_action_runs_beside_the_drive_after_its_node(
    master: Master, demo_robot: TaskManagerClient
) -> None:
    action = photo('NONE')
    master.command('order', order=order('order-none', node('s', 0, 0.0, 0.0, action),
                                        node('t', 2, 1.0, 1.0)))  # fmt: skip

    done = processed(master, 'order-none')

    assert done['error'] is None
    (photo_task,) = ended(demo_robot, f'order-none/{action["actionId"]}')
    assert (photo_task.status, photo_task.mission_id) == (TaskStatus.DONE, '')


def test_instant_actions_in_the_2_0_0_spelling_are_read(master: Master) -> None:
    request = {'actionId': 'state-now', 'actionName': 'stateRequest', 'blockingType': 'HARD'}

    master.command(
        'raw', topic='instantActions', payload=with_header({'instantActions': [request]})
    )

    state = latest_state(
        master,
        lambda s: any(a['actionId'] == 'state-now' for a in s['actionStates']),
        'stateRequest reported',
    )
    (reported,) = [a for a in state['actionStates'] if a['actionId'] == 'state-now']
    assert (reported['actionType'], reported['actionStatus']) == ('stateRequest', 'FINISHED')
