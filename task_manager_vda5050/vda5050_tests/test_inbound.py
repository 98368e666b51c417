"""The vehicle's door, without MQTT or ROS: what an inbound message must be to be acted on
(its size, depth, bounds, schema and header), and the bytes allowed to wait for the worker."""

from typing import Any

import pytest

from task_manager.core.bounds import (
    JSON_MAX_DEPTH,
    TASK_DATA_MAX_BYTES,
    VDA5050_ACTIONS_MAX,
    VDA5050_ID_MAX_CHARACTERS,
    VDA5050_LIST_MAX,
    VDA5050_TEXT_MAX_CHARACTERS,
)
from task_manager_vda5050.adapter import Backlog
from task_manager_vda5050.inbound import read_inbound
from task_manager_vda5050.schemas import Invalid
from task_manager_vda5050.testing import node, order, photo, with_header
from task_manager_vda5050.topics import Vehicle

VEHICLE = Vehicle('acme', 'robot1')


def read(document: dict[str, Any], topic: str = 'order', **header: Any) -> Invalid | None:
    """Why `document` with a header is not acted on (None: it is)."""
    _, invalid = read_inbound(topic, with_header(document, **header).encode(), VEHICLE)
    return invalid


def two_nodes(**first: Any) -> dict[str, Any]:
    document = order('o', node('a', 0, 0.0, 0.0), node('b', 2, 1.0, 0.0))
    document['nodes'][0].update(first)
    return document


def test_an_order_within_every_bound_is_read() -> None:
    long_id = 'n' * VDA5050_ID_MAX_CHARACTERS
    document = order('o' * VDA5050_ID_MAX_CHARACTERS, node(long_id, 0, 0.0, 0.0))
    document['nodes'][0]['nodeDescription'] = 'd' * VDA5050_TEXT_MAX_CHARACTERS
    document['nodes'][0]['actions'] = [photo() for _ in range(VDA5050_ACTIONS_MAX)]

    assert read(document) is None


def test_a_message_over_the_size_bound_is_refused_before_it_is_parsed() -> None:
    payload = b' ' * (TASK_DATA_MAX_BYTES + 1)

    document, invalid = read_inbound('order', payload, VEHICLE)

    assert document is None
    assert invalid == Invalid(
        '', f'the message is {TASK_DATA_MAX_BYTES + 1} bytes; at most {TASK_DATA_MAX_BYTES} allowed'
    )


def test_deep_nesting_a_key_twice_and_nan_are_refused_as_json() -> None:
    deep = b'{"orderId": ' + b'[' * 100_000 + b']' * 100_000 + b'}'

    _, too_deep = read_inbound('order', deep, VEHICLE)
    _, twice = read_inbound('order', b'{"orderId": "a", "orderId": "b"}', VEHICLE)
    _, nan = read_inbound('order', b'{"orderId": NaN}', VEHICLE)

    assert too_deep is not None
    assert f'deeper than {JSON_MAX_DEPTH} levels' in too_deep.message
    assert len(too_deep.message) < 300
    assert twice is not None and "'orderId' is given twice" in twice.message
    assert nan is not None and 'NaN' in nan.message


@pytest.mark.parametrize(
    ('first_node', 'field', 'message'),
    [
        (
            {'nodeId': 'n' * 101},
            'nodes/0/nodeId',
            'nodes/0/nodeId is 101 characters; at most 100 allowed',
        ),
        (
            {'nodeDescription': 'd' * 1001},
            'nodes/0/nodeDescription',
            'nodes/0/nodeDescription is 1001 characters; at most 1000 allowed',
        ),
        ({'k' * 101: 1}, 'nodes/0', 'a key of nodes/0 is 101 characters; at most 100 allowed'),
        (
            {'sequenceId': 2**32},
            'nodes/0/sequenceId',
            'nodes/0/sequenceId must be from 0 to 4294967295, got 4294967296',
        ),
        (
            {'nodePosition': {'x': 1e300, 'y': 0.0, 'mapId': 'm'}},
            'nodes/0/nodePosition/x',
            'nodes/0/nodePosition/x must be from -9007199254740992 to 9007199254740992, got 1e+300',
        ),
        (
            {'actions': [photo() for _ in range(VDA5050_ACTIONS_MAX + 1)]},
            'nodes/0/actions',
            'nodes/0/actions has 101 items; at most 100 allowed',
        ),
    ],
)
def test_a_value_over_its_bound_is_refused_naming_field_and_bound(
    first_node: dict[str, Any], field: str, message: str
) -> None:
    assert read(two_nodes(**first_node)) == Invalid(field, message)


def test_an_order_of_too_many_nodes_is_refused() -> None:
    nodes = [node(f'n{i}', 2 * i, 0.0, 0.0) for i in range(VDA5050_LIST_MAX + 1)]

    invalid = read(order('o', *nodes))

    assert invalid == Invalid('nodes', 'nodes has 1001 items; at most 1000 allowed')


def test_the_keys_of_a_parameter_value_are_not_the_standards() -> None:
    action = {**photo(), 'actionParameters': [{'key': 'camera', 'value': {'key': 'x' * 500}}]}

    assert read(two_nodes(actions=[action])) is None


def test_a_schema_problem_repeats_only_a_cut_of_the_value() -> None:
    invalid = read({**two_nodes(), 'orderUpdateId': 'u' * 900})

    assert invalid is not None
    assert invalid.field == 'orderUpdateId'
    assert invalid.message.startswith("'uuuu")
    assert len(invalid.message) < 300


def test_a_message_for_another_vehicle_is_refused_naming_the_header_field() -> None:
    pause = {'actionId': 'p', 'actionType': 'startPause', 'blockingType': 'HARD'}

    other_serial = read(two_nodes(), serialNumber='robot2')
    other_manufacturer = read({'actions': [pause]}, 'instantActions', manufacturer='evil')

    assert other_serial == Invalid(
        'serialNumber', "serialNumber 'robot2' names another vehicle: this one is 'robot1'"
    )
    assert other_manufacturer is not None and other_manufacturer.field == 'manufacturer'


def test_the_backlog_drops_what_would_exceed_its_bytes_and_counts_it() -> None:
    backlog = Backlog(max_bytes=100)

    admitted = [backlog.admit(size) for size in (60, 40, 1, 30)]
    first_handled = backlog.handled(60)
    after = backlog.admit(30)

    assert admitted == [True, True, False, False]
    assert (first_handled, after, backlog.handled(40)) == (2, True, 0)
