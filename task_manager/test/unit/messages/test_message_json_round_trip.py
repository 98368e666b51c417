"""JSON from ROS 2 messages, and the conversion's properties: every message round-trips, and
any JSON text or dict gives a message or a TaskDataError (no DDS needed). Reading JSON into
messages, field by field, is test_message_json.py."""

import json
import math
from typing import Any

import pytest
from builtin_interfaces.msg import Time
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rosidl_parser import definition as idl
from test_msgs.action import Fibonacci
from test_msgs.msg import (
    Arrays,
    BasicTypes,
    BoundedSequences,
    Builtins,
    Empty,
    Nested,
    Strings,
    UnboundedSequences,
    WStrings,
)

from task_manager.messages.json_codec import (
    TaskDataError,
    message_from_dict,
    message_from_json,
    message_to_dict,
    message_to_json,
)
from task_manager.testing.messages import GeneratedMessage

Goal = Fibonacci.Goal
FAST = settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# --- output --------------------------------------------------------------------------------


def _assert_plain(value: Any) -> None:
    """Fail unless ``value`` is made of plain JSON-like Python values only."""
    if isinstance(value, dict):
        for item in value.values():
            _assert_plain(item)
    elif isinstance(value, list):
        for item in value:
            _assert_plain(item)
    else:
        assert type(value) in (int, float, bool, str), (value, type(value))


@pytest.mark.parametrize(
    'msg_class',
    [BasicTypes, Arrays, BoundedSequences, UnboundedSequences, Nested, Strings, WStrings],
)
def test_to_dict_has_every_field_in_order_as_plain_values(
    msg_class: type[GeneratedMessage],
) -> None:
    data = message_to_dict(msg_class())
    assert list(data) == list(msg_class.get_fields_and_field_types())
    _assert_plain(data)


def test_bytes_become_ints() -> None:
    assert message_to_dict(BasicTypes(byte_value=b'\x07'))['byte_value'] == 7
    data = message_to_dict(UnboundedSequences(byte_values=[b'\x01', b'\xff']))
    assert data['byte_values'] == [1, 255]
    as_bytes = UnboundedSequences()
    as_bytes.byte_values = b'\x01\x02'
    assert message_to_dict(as_bytes)['byte_values'] == [1, 2]
    assert message_to_dict(Arrays())['uint8_values'] == [0, 0, 0]


def test_to_json_is_compact_keeps_unicode_and_nulls_non_finite() -> None:
    assert message_to_json(Goal(order=5)) == '{"order":5}'
    assert '"string_value":"héllo ✓"' in message_to_json(Strings(string_value='héllo ✓'))
    msg = BasicTypes(float64_value=math.nan, float32_value=math.inf)
    assert math.isnan(message_to_dict(msg)['float64_value'])
    text = message_to_json(msg)
    assert '"float64_value":null' in text
    assert '"float32_value":null' in text
    arrays = UnboundedSequences(float64_values=[1.0, -math.inf])
    assert json.loads(message_to_json(arrays))['float64_values'] == [1.0, None]


# --- properties ----------------------------------------------------------------------------


def _values(slot: idl.AbstractType) -> st.SearchStrategy[Any]:
    """Generate valid JSON-side values for a field type (independently of the module)."""
    if isinstance(slot, idl.Array):
        return st.lists(_values(slot.value_type), min_size=slot.size, max_size=slot.size)
    if isinstance(slot, idl.AbstractSequence):
        limit = slot.maximum_size if isinstance(slot, idl.BoundedSequence) else 4
        return st.lists(_values(slot.value_type), max_size=limit)
    if isinstance(slot, idl.NamespacedType):
        module = __import__('.'.join(slot.namespaces), fromlist=[slot.name])
        return _full_dicts(getattr(module, slot.name))
    if isinstance(slot, idl.BoundedString | idl.BoundedWString):
        return st.text(max_size=int(slot.maximum_size))
    if isinstance(slot, idl.AbstractGenericString):
        return st.text(max_size=30)
    if not isinstance(slot, idl.BasicType):
        raise TypeError(f'no strategy for the ROS field type {slot!r}')
    name = slot.typename
    if name == 'boolean':
        return st.booleans()
    if name == 'octet':
        return st.integers(0, 255)
    if name in ('float', 'double'):
        return st.floats(allow_nan=False, allow_infinity=False, width=32 if name == 'float' else 64)
    bits = int(name.lstrip('uint'))
    if name.startswith('u'):
        return st.integers(0, 2**bits - 1)
    return st.integers(-(2 ** (bits - 1)), 2 ** (bits - 1) - 1)


def _full_dicts(msg_class: type[GeneratedMessage]) -> st.SearchStrategy[dict[str, Any]]:
    """Generate complete field dicts for a message class."""
    names = msg_class.get_fields_and_field_types()
    slots = msg_class.SLOT_TYPES
    return st.fixed_dictionaries(
        {name: _values(slot) for name, slot in zip(names, slots, strict=True)}
    )


ROUND_TRIP_CLASSES = [
    BasicTypes,
    Arrays,
    BoundedSequences,
    UnboundedSequences,
    Nested,
    Strings,
    WStrings,
    Time,
    Builtins,
]


@pytest.mark.parametrize('msg_class', ROUND_TRIP_CLASSES)
def test_round_trip(msg_class: type[GeneratedMessage]) -> None:
    @FAST
    @given(_full_dicts(msg_class))
    def check(data: dict[str, Any]) -> None:
        msg = message_from_dict(msg_class, data)
        assert message_to_dict(msg) == data
        assert message_from_dict(msg_class, message_to_dict(msg)) == msg
        assert message_from_json(msg_class, message_to_json(msg)) == msg

    check()


FUZZ_CLASSES = [Goal, BasicTypes, Nested, BoundedSequences, Builtins, Strings, Empty]
FIELD_NAMES = sorted(
    {name for cls in FUZZ_CLASSES for name in cls.get_fields_and_field_types()}
    | {'sec', 'nanosec', 'int8_value'}
)
JSON_SCALARS = (
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats()
    | st.text()
    | st.builds(str.__mul__, st.sampled_from(['x', 'ö', '🤖', '"']), st.integers(1000, 200_000))
)
JSON_VALUES = st.recursive(
    JSON_SCALARS,
    lambda inner: (
        st.lists(inner, max_size=5)
        | st.dictionaries(st.sampled_from(FIELD_NAMES) | st.text(max_size=8), inner, max_size=5)
    ),
    max_leaves=20,
)
DEEP = st.integers(1, 3000).map(lambda depth: '[' * depth + ']' * depth)


@settings(max_examples=80, deadline=None, suppress_health_check=list(HealthCheck))
@given(
    st.sampled_from(FUZZ_CLASSES),
    st.one_of(JSON_VALUES.map(json.dumps), st.text(max_size=50), DEEP),
)
def test_any_json_text_gives_a_message_or_a_task_data_error(
    msg_class: type[GeneratedMessage], text: str
) -> None:
    try:
        msg = message_from_json(msg_class, text)
    except TaskDataError as error:
        assert isinstance(error.field, str)
    else:
        assert isinstance(msg, msg_class)


@settings(max_examples=50, deadline=None, suppress_health_check=list(HealthCheck))
@given(
    st.sampled_from(FUZZ_CLASSES),
    st.dictionaries(
        st.sampled_from(FIELD_NAMES) | st.integers() | st.none(),
        JSON_VALUES | st.binary() | st.tuples(st.integers()) | st.sets(st.integers()),
        max_size=6,
    ),
)
def test_any_dict_gives_a_message_or_a_task_data_error(
    msg_class: type[GeneratedMessage], data: dict[str, Any]
) -> None:
    try:
        msg = message_from_dict(msg_class, data)
    except TaskDataError as error:
        assert isinstance(error.field, str)
    else:
        assert isinstance(msg, msg_class)
