"""What the vehicle's state keeps and shows, and how a state too large for the broker goes
out shortened, without MQTT or ROS: every list bounded, each cut said in the standard's terms."""

from typing import Any

from task_manager.core.bounds import (
    ECHO_MAX_CHARACTERS,
    VDA5050_STATE_ACTIONS_MAX,
    VDA5050_STATE_ERRORS_MAX,
)
from task_manager_vda5050.orders.plan import Rejection
from task_manager_vda5050.schemas import problems
from task_manager_vda5050.state.fitting import shortened, size
from task_manager_vda5050.state.vehicle_state import VehicleState
from task_manager_vda5050.testing import node, order

HEADER = {'headerId': 1, 'timestamp': '2024-01-01T00:00:00.000Z', 'version': '2.0.0',
          'manufacturer': 'acme', 'serialNumber': 'robot1'}  # fmt: skip


def action(action_id: str, description: str = '') -> dict[str, Any]:
    described = {'actionDescription': description} if description else {}
    return {'actionId': action_id, 'actionType': 'stateRequest', 'blockingType': 'HARD',
            **described}  # fmt: skip


def test_an_error_echoes_only_a_cut_of_what_it_is_about() -> None:
    state = VehicleState()

    state.add_error(Rejection('validationError', 'x' * 600_000, (('actionType', 'y' * 600_000),)))

    (error,) = state.document()['errors']
    assert len(error['errorDescription']) < 1100
    assert len(error['errorReferences'][0]['referenceValue']) < ECHO_MAX_CHARACTERS + 40


def test_errors_beyond_the_bound_are_left_out_and_one_error_says_how_many() -> None:
    state = VehicleState()
    for number in range(VDA5050_STATE_ERRORS_MAX + 5):
        state.add_error(Rejection('orderError', f'order error {number}'))
    state.add_error(Rejection('instantActionError', 'an instant error'))

    errors = state.document()['errors']
    state.clear_errors(('orderError',))

    assert len(errors) == VDA5050_STATE_ERRORS_MAX
    note = errors[0]
    assert (note['errorType'], note['errorDescription']) == (
        'errorsLeftOut',
        f'7 older errors left out: state shows the newest {VDA5050_STATE_ERRORS_MAX - 1}',
    )
    assert note['errorReferences'] == [{'referenceKey': 'leftOut', 'referenceValue': '7'}]
    assert errors[-1]['errorDescription'] == 'an instant error'
    assert [e['errorType'] for e in state.document()['errors']] == ['instantActionError']


def test_beyond_the_bound_ended_actions_are_forgotten_and_the_rest_noted() -> None:
    state = VehicleState()
    state.add_instant(action('first'))
    state.set_action('first', 'FINISHED')
    many = [node(f'n{i}', 2 * i, 0.0, 0.0) for i in range(VDA5050_STATE_ACTIONS_MAX + 1)]
    for each in many:
        each['actions'] = [action(f'a-{each["nodeId"]}')]

    state.take_order(order('big', *many), stitched=False)

    document = state.document()
    assert 'first' not in state.action_states
    assert len(document['actionStates']) == VDA5050_STATE_ACTIONS_MAX
    assert document['actionStates'][0]['actionId'] == 'a-n0'
    (note,) = document['information']
    assert (note['infoType'], note['infoReferences']) == (
        'actionStatesLeftOut',
        [{'referenceKey': 'leftOut', 'referenceValue': '1'}],
    )


def test_a_state_that_fits_goes_out_as_it_is() -> None:
    document = VehicleState().document()

    assert shortened(document, 10_000) == (document, '')


def test_a_state_too_large_loses_its_descriptions_first() -> None:
    state = VehicleState()
    for number in range(30):
        state.add_instant(action(f'a{number}', 'd' * 900))

    short, words = shortened(state.document(), 16_384)

    assert words == 'descriptions'
    assert [a['actionId'] for a in short['actionStates']] == [f'a{n}' for n in range(30)]
    assert all('actionDescription' not in a for a in short['actionStates'])
    assert short['information'][-1]['infoType'] == 'stateShortened'
    assert size(short) <= 16_384
    assert problems('state', {**HEADER, **short}) == []


def test_then_ended_actions_go_first_and_the_farthest_nodes() -> None:
    nodes = [node(f'n{i}', 2 * i, 0.0, 0.0) for i in range(400)]
    state = VehicleState()
    state.take_order(order('long', *nodes), stitched=False)
    for number in range(40):
        state.add_instant(action(f'a{number}'))
        state.set_action(f'a{number}', 'FINISHED' if number < 30 else 'RUNNING')

    short, words = shortened(state.document(), 8_192)

    assert size(short) <= 8_192
    kept = [a['actionId'] for a in short['actionStates']]
    assert kept == [f'a{n}' for n in range(20, 40)]  # the oldest ended ones went
    node_ids = [n['nodeId'] for n in short['nodeStates']]
    assert node_ids == [f'n{i}' for i in range(len(node_ids))]  # the nearest ones stay
    references = {r['referenceKey']: int(r['referenceValue'])
                  for r in short['information'][-1]['infoReferences']}  # fmt: skip
    assert (references['nodeStates'], references['actionStates']) == (400 - len(node_ids), 20)
    assert f'{references["nodeStates"]} nodeStates' in words
    assert problems('state', {**HEADER, **short}) == []
