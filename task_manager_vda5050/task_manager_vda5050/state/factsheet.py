"""The factsheet: the vehicle as the mapping describes it, and every action it carries out
(the built-in instant actions and the mapped ones) with its scopes, parameters and the
blocking types its task allows (one that holds the navigation's resources, or is
blocking, cannot run while driving: no NONE).

The blocking types are said at the end of actionDescription ("Blocking types: NONE, SOFT,
HARD."), not in `blockingTypes`: the 2.1.0 schema puts that field's enum on the array
itself, so that no list of blocking types is valid against it, and every message sent must
be valid against both 2.0.0 and 2.1.0.
"""

from collections.abc import Callable
from typing import Any

from task_manager.core.bounds import (
    TASK_DATA_MAX_BYTES,
    VDA5050_ACTIONS_MAX,
    VDA5050_ID_MAX_CHARACTERS,
    VDA5050_LIST_MAX,
    VDA5050_STATE_ACTIONS_MAX,
    VDA5050_STATE_ERRORS_MAX,
)
from task_manager_vda5050.mapping import ActionMapping, Mapping

BUILT_IN = {
    'startPause': 'Pause the order: driving stops, the running tasks that can pause pause.',
    'stopPause': 'Resume the paused order.',
    'cancelOrder': "Cancel the order's tasks; the vehicle stops.",
    'stateRequest': 'Publish the state now.',
    'factsheetRequest': 'Publish the factsheet now.',
}
DEFAULT_VEHICLE: dict[str, dict[str, Any]] = {
    'typeSpecification': {
        'seriesName': 'task-manager',
        'agvKinematic': 'DIFF',
        'agvClass': 'CARRIER',
        'maxLoadMass': 0.0,
        'localizationTypes': ['NATURAL'],
        'navigationTypes': ['AUTONOMOUS'],
    },
    'physicalParameters': {
        'speedMin': 0.0,
        'speedMax': 1.0,
        'accelerationMax': 1.0,
        'decelerationMax': 1.0,
        'heightMax': 1.0,
        'width': 0.5,
        'length': 0.5,
    },
    'agvGeometry': {},
    'loadSpecification': {},
}
PROTOCOL_LIMITS = {
    # the bounds of core/bounds.py the vehicle's door (inbound.py) and its state keep
    'maxStringLens': {
        'msgLen': TASK_DATA_MAX_BYTES,
        'idLen': VDA5050_ID_MAX_CHARACTERS,
        'enumLen': VDA5050_ID_MAX_CHARACTERS,
    },
    'maxArrayLens': {
        'order.nodes': VDA5050_LIST_MAX,
        'order.edges': VDA5050_LIST_MAX,
        'node.actions': VDA5050_ACTIONS_MAX,
        'edge.actions': VDA5050_ACTIONS_MAX,
        'actions.actionsParameters': VDA5050_ACTIONS_MAX,
        'instantActions': VDA5050_ACTIONS_MAX,
        'trajectory.knotVector': VDA5050_LIST_MAX,
        'trajectory.controlPoints': VDA5050_LIST_MAX,
        'state.nodeStates': VDA5050_LIST_MAX,
        'state.edgeStates': VDA5050_LIST_MAX,
        'state.actionStates': VDA5050_STATE_ACTIONS_MAX,
        'state.errors': VDA5050_STATE_ERRORS_MAX,
    },
    'timing': {'minOrderInterval': 0.0, 'minStateInterval': 0.0, 'defaultStateInterval': 30.0},
}
VALUE_TYPES = (
    (bool, 'BOOL'),
    (int, 'INTEGER'),
    (float, 'FLOAT'),
    (str, 'STRING'),
    (list, 'ARRAY'),
    (dict, 'OBJECT'),
)


def factsheet(mapping: Mapping, drives_or_blocks: Callable[[str], bool]) -> dict[str, Any]:
    """The factsheet's fields, without the header."""
    built_in = [
        {
            'actionType': name,
            'actionDescription': f'{words} {blocking_words(["HARD"])}',
            'actionScopes': ['INSTANT'],
        }
        for name, words in BUILT_IN.items()
    ]
    mapped = [
        _action(name, action, drives_or_blocks(action.task_name))
        for name, action in mapping.actions.items()
    ]
    return {
        **{key: mapping.vehicle.get(key, value) for key, value in DEFAULT_VEHICLE.items()},
        'protocolLimits': PROTOCOL_LIMITS,
        'protocolFeatures': {'optionalParameters': [], 'agvActions': [*built_in, *mapped]},
    }


def _action(name: str, action: ActionMapping, drives_or_blocks: bool) -> dict[str, Any]:
    blocking = ['SOFT', 'HARD'] if drives_or_blocks else ['NONE', 'SOFT', 'HARD']
    words = f'{action.description} ' if action.description else ''
    described: dict[str, Any] = {
        'actionType': name,
        'actionDescription': words + blocking_words(blocking),
        'actionScopes': list(action.scopes),
    }
    described['actionParameters'] = [
        {
            'key': key,
            'valueDataType': _value_type(action.defaults.get(key, '')),
            'isOptional': key in action.defaults,
        }
        for key in action.names
    ]
    described['resultDescription'] = f'the result of the task {action.task_name}'
    return described


def blocking_words(blocking_types: list[str]) -> str:
    return f'Blocking types: {", ".join(blocking_types)}.'


def _value_type(value: Any) -> str:
    return next((name for kind, name in VALUE_TYPES if isinstance(value, kind)), 'STRING')
