"""Orders checked and planned against the demo's mapping, without MQTT or ROS."""

from typing import Any

import pytest

from task_manager_vda5050.mapping import DEMO_MAPPING, read_mapping
from task_manager_vda5050.orders.plan import OrderRejectedError, Planner, check_update
from task_manager_vda5050.testing import edge, node, order, photo

PLANNER = Planner(read_mapping(DEMO_MAPPING), {'navigation/navigate_to_pose'}.__contains__)


def rejection(document: dict[str, Any], stitched: bool = False) -> tuple[str, dict[str, str]]:
    with pytest.raises(OrderRejectedError) as raised:
        PLANNER.plan(document, document['orderId'], stitched)
    error = raised.value.rejection
    return error.error_type, dict(error.references)


def test_a_node_is_a_drive_then_its_hard_actions_and_none_actions_start_beside() -> None:
    hard, beside = photo('HARD', 'front'), photo('NONE', 'rear')
    plan = PLANNER.plan(
        order('o', node('a', 0, 0.0, 0.0), node('b', 2, 1.0, 2.0, hard, beside)), 'o', False
    )

    assert [(t.task_id, t.task_name, t.task_data) for t in plan.steps] == [
        ('o/a/0', 'navigation/navigate_to_pose', {'x': 0.0, 'y': 0.0, 'theta': 0.0}),
        ('o/b/2', 'navigation/navigate_to_pose', {'x': 1.0, 'y': 2.0, 'theta': 0.0}),
        (f'o/{hard["actionId"]}', 'camera/take_photo', {'camera': 'front'}),
    ]
    assert [t.task_data for t in plan.after_reaching['o/b/2']] == [{'camera': 'rear'}]
    assert plan.last_base == ('b', 2)


def test_horizon_nodes_start_nothing_and_an_update_skips_the_node_it_starts_at() -> None:
    document = order('o', node('a', 0, 0.0, 0.0), node('b', 2, 1.0, 0.0))
    document['nodes'][1]['released'] = document['edges'][0]['released'] = False
    assert [t.task_id for t in PLANNER.plan(document, 'o', False).steps] == ['o/a/0']

    update = {**order('o', node('a', 0, 0.0, 0.0), node('b', 2, 1.0, 0.0)), 'orderUpdateId': 1}
    assert [t.task_id for t in PLANNER.plan(update, 'o/update/1', True).steps] == ['o/b/2']


def test_an_unmapped_action_or_a_missing_position_is_refused_with_its_reference() -> None:
    dance = {'actionId': 'd', 'actionType': 'dance', 'blockingType': 'HARD'}
    nowhere = node('b', 2, 0.0, 0.0)
    del nowhere['nodePosition']

    assert rejection(order('o', node('a', 0, 0.0, 0.0, dance))) == (
        'orderError',
        {'topic': 'order', 'headerId': '', 'orderId': 'o', 'orderUpdateId': '0',
         'nodeId': 'a', 'actionId': 'd', 'actionType': 'dance'},
    )  # fmt: skip
    assert rejection(order('o', node('a', 0, 0.0, 0.0), nowhere))[0] == 'noRouteError'


def test_a_none_action_whose_task_cannot_run_while_driving_is_refused() -> None:
    planner = Planner(read_mapping(DEMO_MAPPING), {'camera/take_photo'}.__contains__)

    with pytest.raises(OrderRejectedError, match='blocking type NONE is not possible'):
        planner.plan(order('o', node('a', 0, 0.0, 0.0, photo('NONE'))), 'o', False)


def test_an_inconsistent_graph_is_a_validation_error() -> None:
    a, b = node('a', 0, 0.0, 0.0), node('b', 2, 1.0, 0.0)
    wrong_edge = {**order('o', a, b), 'edges': [{**edge(b, a), 'sequenceId': 1}]}
    horizon_first = order('o', a, b)
    horizon_first['nodes'][0]['released'] = False

    assert rejection(wrong_edge)[0] == 'validationError'
    assert rejection(horizon_first)[0] == 'validationError'


def test_an_update_must_be_newer_and_start_at_the_last_base_node() -> None:
    update = {**order('o', node('b', 2, 1.0, 0.0), node('c', 4, 2.0, 0.0)), 'orderUpdateId': 2}

    assert check_update(update, 'o', 1, ('b', 2)) is True
    assert check_update(update, 'o', 2, ('b', 2)) is False  # the same update again
    with pytest.raises(OrderRejectedError, match='older'):
        check_update(update, 'o', 3, ('b', 2))
    with pytest.raises(OrderRejectedError, match='last base node a'):
        check_update(update, 'o', 1, ('a', 0))


def test_an_action_id_twice_or_in_use_is_a_validation_error_naming_it() -> None:
    first, second = photo(), photo()
    twice = order('o', node('a', 0, 0.0, 0.0, first), node('b', 2, 1.0, 0.0, {**second,
                  'actionId': first['actionId']}))  # fmt: skip
    used = order('o', node('a', 0, 0.0, 0.0), node('b', 2, 1.0, 0.0, second))

    assert rejection(twice)[0] == 'validationError'
    assert rejection(twice)[1]['actionId'] == first['actionId']
    with pytest.raises(OrderRejectedError, match='is used already') as raised:
        PLANNER.plan(used, 'o', False, action_ids_in_use={second['actionId']})
    assert dict(raised.value.rejection.references)['actionId'] == second['actionId']


def test_an_update_may_repeat_the_actions_of_the_node_it_starts_at() -> None:
    action = photo()
    update = {**order('o', node('b', 2, 1.0, 0.0, action), node('c', 4, 2.0, 0.0)),
              'orderUpdateId': 1}  # fmt: skip

    segment = PLANNER.plan(update, 'o/update/1', True, action_ids_in_use={action['actionId']})

    assert [t.task_id for t in segment.steps] == ['o/c/4']


def test_an_action_id_that_makes_a_drives_task_id_is_a_validation_error() -> None:
    clash = {**photo(), 'actionId': 'b/2'}
    edge_clash = order('o', node('a', 0, 0.0, 0.0), node('b', 2, 1.0, 0.0))
    edge_clash['edges'][0]['actions'] = [clash]

    assert rejection(order('o', node('a', 0, 0.0, 0.0), node('b', 2, 1.0, 0.0, clash))) == (
        'validationError',
        {'topic': 'order', 'headerId': '', 'orderId': 'o', 'orderUpdateId': '0', 'actionId': 'b/2'},
    )
    assert rejection(edge_clash)[1]['actionId'] == 'b/2'  # the edge's action comes first
    with pytest.raises(OrderRejectedError, match='the drive to node b'):
        PLANNER.plan(order('o', node('b', 2, 1.0, 0.0)), 'o', False, task_ids_in_use={'o/b/2'})


def test_a_base_of_more_tasks_than_a_mission_takes_is_a_validation_error() -> None:
    nodes = [node(f'n{i}', 2 * i, float(i), 0.0, photo(), photo()) for i in range(334)]

    error_type, _ = rejection(order('o', *nodes))

    assert error_type == 'validationError'
    with pytest.raises(OrderRejectedError, match='makes 1002 tasks'):
        PLANNER.plan(order('o', *nodes), 'o', False)
