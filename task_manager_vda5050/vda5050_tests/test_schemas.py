"""Inbound messages read against the official schemas (the SDK's files), and what the SDK's
own models do with them: why the adapter reads them itself."""

import json

from vda5050.model.instant_actions import InstantActions

from task_manager_vda5050.inbound import read_inbound
from task_manager_vda5050.topics import Vehicle

VEHICLE = Vehicle('acme', 'robot1')

HEADER = {'headerId': 1, 'timestamp': '2024-01-01T00:00:00.00Z', 'version': '2.0.0',
          'manufacturer': 'acme', 'serialNumber': 'robot1'}  # fmt: skip
PAUSE_2_0 = {**HEADER, 'instantActions': [
    {'actionId': 'p', 'actionName': 'startPause', 'blockingType': 'HARD'}
]}  # fmt: skip


def test_instant_actions_in_the_2_0_0_spelling_are_read_as_2_1_0_spells_them() -> None:
    document, invalid = read_inbound('instantActions', json.dumps(PAUSE_2_0).encode(), VEHICLE)

    assert invalid is None
    assert document is not None
    assert document['actions'] == [
        {'actionId': 'p', 'actionType': 'startPause', 'blockingType': 'HARD'}
    ]


def test_the_sdk_model_would_read_a_2_0_0_pause_as_no_action_at_all() -> None:
    assert InstantActions.model_validate(PAUSE_2_0).actions == []


def test_a_malformed_message_names_its_field_and_text_that_is_no_json_says_so() -> None:
    bad_node = {'nodeId': 'a', 'sequenceId': -1, 'released': True, 'actions': []}
    order = {**HEADER, 'orderId': 'o', 'orderUpdateId': 0, 'edges': [], 'nodes': [bad_node]}

    _, invalid = read_inbound('order', json.dumps(order).encode(), VEHICLE)
    _, not_json = read_inbound('order', b'{"orderId": ', VEHICLE)

    assert invalid is not None and invalid.field == 'nodes/0/sequenceId'
    assert not_json is not None and not_json.message.startswith('not valid JSON')
