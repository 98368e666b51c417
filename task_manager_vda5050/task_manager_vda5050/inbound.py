"""The vehicle's door: what an inbound message must be to be acted on.

Checked in this order, the first problem found refusing the message (a validationError in
state, naming the field and the bound):

1. its size: at most TASK_DATA_MAX_BYTES;
2. plain JSON (the shared `protocol/strict_json.py`): nested at most JSON_MAX_DEPTH levels,
   no key twice in an object, no NaN or infinity;
3. the VDA 5050 bounds of `core/bounds.py` on every string, list and number (bounds_problem);
4. the official schema (schemas.py), the 2.0.0 spelling of instantActions read as 2.1.0's;
5. a header naming this vehicle (its manufacturer and serialNumber).
"""

from typing import Any

from task_manager.core.bounds import (
    JSON_MAX_DEPTH,
    TASK_DATA_MAX_BYTES,
    VDA5050_ACTIONS_MAX,
    VDA5050_ID_MAX_CHARACTERS,
    VDA5050_LIST_MAX,
    VDA5050_NUMBER,
    VDA5050_TEXT_MAX_CHARACTERS,
    VDA5050_UINT32,
    cut_text,
)
from task_manager.protocol.strict_json import RefusedJsonError, load
from task_manager_vda5050.schemas import Invalid, instant_actions_of_2_0, problems
from task_manager_vda5050.topics import Vehicle

ID_KEYS = frozenset(
    ('orderId', 'zoneSetId', 'nodeId', 'mapId', 'actionId', 'edgeId', 'startNodeId', 'endNodeId')
)
"""The factsheet's idLen applies to them."""
ENUM_KEYS = frozenset(('actionType', 'blockingType', 'direction', 'key'))
"""The factsheet's enumLen applies to them."""
NAME_KEYS = ID_KEYS | ENUM_KEYS
"""Strings of at most VDA5050_ID_MAX_CHARACTERS; every other one VDA5050_TEXT_MAX_CHARACTERS."""
UINT32_KEYS = frozenset(('headerId', 'orderUpdateId', 'sequenceId'))
ACTION_LISTS = frozenset(('actions', 'instantActions', 'actionParameters'))
"""Lists of at most VDA5050_ACTIONS_MAX items; every other one VDA5050_LIST_MAX."""
FREE_VALUE = 'value'
"""An actionParameter's value: any JSON, whose keys mean nothing to the standard."""


def read_inbound(
    topic: str, payload: bytes, vehicle: Vehicle
) -> tuple[dict[str, Any] | None, Invalid | None]:
    """The message of an inbound payload when it may be acted on, else why not."""
    if len(payload) > TASK_DATA_MAX_BYTES:
        return None, Invalid(
            '', f'the message is {len(payload)} bytes; at most {TASK_DATA_MAX_BYTES} allowed'
        )
    try:
        document = load(payload, JSON_MAX_DEPTH)
    except RefusedJsonError as refused:
        return None, Invalid('', cut_text(refused.message))
    if topic == 'instantActions':
        document = instant_actions_of_2_0(document)
    invalid = bounds_problem(document)
    if invalid is None:
        found = problems(topic, document)
        invalid = found[0] if found else _other_vehicle(document, vehicle)
    return (None, invalid) if invalid else (document, None)


def bounds_problem(document: Any) -> Invalid | None:
    """The first string (a key too), list or number of `document` beyond its bound, or None."""
    found = _problem(document, (), names=True)
    return None if found is None else Invalid(cut_text(found.field), cut_text(found.message))


def _problem(value: Any, path: tuple[str | int, ...], names: bool) -> Invalid | None:
    """`names`: the keys mean what the standard says (not inside an actionParameter's value)."""
    key = path[-1] if path else ''
    field = '/'.join(str(p) for p in path)
    if isinstance(value, str):
        limit = (
            VDA5050_ID_MAX_CHARACTERS if names and key in NAME_KEYS else VDA5050_TEXT_MAX_CHARACTERS
        )
        if len(value) > limit:
            return Invalid(field, f'{field} is {len(value)} characters; at most {limit} allowed')
    elif isinstance(value, int | float) and not isinstance(value, bool):
        bound = VDA5050_UINT32 if names and key in UINT32_KEYS else VDA5050_NUMBER
        if problem := bound.problem(field, value):
            return Invalid(field, problem)
    elif isinstance(value, list):
        limit = VDA5050_ACTIONS_MAX if names and key in ACTION_LISTS else VDA5050_LIST_MAX
        if len(value) > limit:
            return Invalid(field, f'{field} has {len(value)} items; at most {limit} allowed')
        for index, item in enumerate(value):
            if found := _problem(item, (*path, index), names):
                return found
    elif isinstance(value, dict):
        if long_key := next((k for k in value if len(k) > VDA5050_ID_MAX_CHARACTERS), None):
            where = f'a key of {field}' if field else 'a key'
            return Invalid(
                field,
                f'{where} is {len(long_key)} characters; at most {VDA5050_ID_MAX_CHARACTERS} '
                'allowed',
            )
        for name, item in value.items():
            if found := _problem(item, (*path, name), names and name != FREE_VALUE):
                return found
    return None


def _other_vehicle(document: dict[str, Any], vehicle: Vehicle) -> Invalid | None:
    """A header that names another vehicle than this one (the schema has made sure it has
    both fields)."""
    for field, own in (
        ('manufacturer', vehicle.manufacturer),
        ('serialNumber', vehicle.serial_number),
    ):
        if document[field] != own:
            return Invalid(
                field,
                f'{field} {cut_text(document[field])!r} names another vehicle: this one is {own!r}',
            )
    return None
