"""Reading JSON into ROS 2 messages: each field's checks, limits and defaults, and what is
refused with which message (no DDS needed). The other way and the properties are
test_message_json_round_trip.py."""

import json
import math
import time
from typing import Any

import pytest
import test_msgs.msg
from builtin_interfaces.msg import Duration, Time
from hypothesis import HealthCheck, settings
from rosidl_parser import definition as idl
from std_srvs.srv import Trigger
from test_msgs.action import Fibonacci
from test_msgs.msg import (
    Arrays,
    BasicTypes,
    BoundedSequences,
    Builtins,
    Defaults,
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

Goal = Fibonacci.Goal
FAST = settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])


class FakeChars:
    """A hand-made message class with IDL types test_msgs does not use."""

    SLOT_TYPES = (
        idl.BasicType('char'),
        idl.BasicType('wchar'),
        idl.Array(idl.BasicType('char'), 2),
        idl.BasicType('long'),
        idl.BasicType('unsigned short'),
        idl.BasicType('long double'),
    )

    def __init__(self) -> None:
        """Set the defaults rosidl would."""
        self.c = chr(0)
        self.w = chr(0)
        self.cs = [chr(0), chr(0)]
        self.n = 0
        self.u = 0
        self.d = 0.0

    @classmethod
    def get_fields_and_field_types(cls) -> dict[str, str]:
        """Return the fields like a generated class does."""
        return {'c': 'char', 'w': 'wchar', 'cs': 'char[2]', 'n': 'long', 'u': 'uint16', 'd': 'ld'}

    def __eq__(self, other: object) -> bool:
        """Compare field by field."""
        return isinstance(other, FakeChars) and vars(self) == vars(other)


class Picky:
    """A message class whose setter rejects everything, like a generated one with checks on."""

    SLOT_TYPES = (idl.BasicType('int32'),)

    @classmethod
    def get_fields_and_field_types(cls) -> dict[str, str]:
        """Return the only field."""
        return {'value': 'int32'}

    @property
    def value(self) -> int:
        """Return nothing useful."""
        return 0

    @value.setter
    def value(self, value: int) -> None:
        raise AssertionError('the setter refuses')


# --- errors --------------------------------------------------------------------------------

BAD_FIELDS: list[tuple[type, str, str, str]] = [
    (Goal, '{"order": "abc"}', 'order', 'int32'),
    (Goal, '{"order": 1.5}', 'order', 'int32'),
    (Goal, '{"order": 1.0}', 'order', 'int32'),
    (Goal, '{"order": true}', 'order', 'int32'),
    (Goal, '{"order": false}', 'order', 'int32'),
    (Goal, '{"order": null}', 'order', 'int32'),
    (Goal, '{"order": [1]}', 'order', 'int32'),
    (Goal, '{"order": {"a": 1}}', 'order', 'int32'),
    (Goal, '{"order": 2147483648}', 'order', 'int32'),
    (Goal, '{"order": -2147483649}', 'order', 'int32'),
    (BasicTypes, '{"int8_value": 128}', 'int8_value', 'int8'),
    (BasicTypes, '{"int8_value": -129}', 'int8_value', 'int8'),
    (BasicTypes, '{"uint8_value": -1}', 'uint8_value', 'uint8'),
    (BasicTypes, '{"uint8_value": 256}', 'uint8_value', 'uint8'),
    (BasicTypes, '{"int16_value": 32768}', 'int16_value', 'int16'),
    (BasicTypes, '{"uint16_value": 65536}', 'uint16_value', 'uint16'),
    (BasicTypes, '{"uint32_value": 4294967296}', 'uint32_value', 'uint32'),
    (BasicTypes, '{"int64_value": 9223372036854775808}', 'int64_value', 'int64'),
    (BasicTypes, '{"uint64_value": 18446744073709551616}', 'uint64_value', 'uint64'),
    (BasicTypes, '{"uint64_value": -1}', 'uint64_value', 'uint64'),
    (BasicTypes, '{"float64_value": true}', 'float64_value', 'float64'),
    (BasicTypes, '{"float64_value": "1.0"}', 'float64_value', 'float64'),
    (BasicTypes, '{"float64_value": null}', 'float64_value', 'float64'),
    (BasicTypes, '{"float64_value": [1.0]}', 'float64_value', 'float64'),
    (BasicTypes, '{"float64_value": %s}' % ('9' * 400), 'float64_value', 'float64'),
    (BasicTypes, '{"float32_value": 3.5e38}', 'float32_value', 'float32'),
    (BasicTypes, '{"float32_value": -3.5e38}', 'float32_value', 'float32'),
    (BasicTypes, '{"float32_value": false}', 'float32_value', 'float32'),
    (BasicTypes, '{"bool_value": 1}', 'bool_value', 'bool'),
    (BasicTypes, '{"bool_value": 0}', 'bool_value', 'bool'),
    (BasicTypes, '{"bool_value": "true"}', 'bool_value', 'bool'),
    (BasicTypes, '{"bool_value": null}', 'bool_value', 'bool'),
    (BasicTypes, '{"byte_value": 256}', 'byte_value', 'byte'),
    (BasicTypes, '{"byte_value": -1}', 'byte_value', 'byte'),
    (BasicTypes, '{"byte_value": "a"}', 'byte_value', 'byte'),
    (BasicTypes, '{"byte_value": true}', 'byte_value', 'byte'),
    (BasicTypes, '{"byte_value": 1.0}', 'byte_value', 'byte'),
    (BasicTypes, '{"char_value": "a"}', 'char_value', 'uint8'),
    (Strings, '{"string_value": 1}', 'string_value', 'string'),
    (Strings, '{"string_value": null}', 'string_value', 'string'),
    (Strings, '{"string_value": true}', 'string_value', 'string'),
    (Strings, '{"string_value": ["a"]}', 'string_value', 'string'),
    (Strings, '{"string_value": "\\ud800"}', 'string_value', 'string'),
    (Strings, '{"bounded_string_value": "%s"}' % ('x' * 23), 'bounded_string_value', 'string<=22'),
    (Strings, '{"bounded_string_value": "%s"}' % ('ö' * 23), 'bounded_string_value', 'string<=22'),
    (BoundedSequences, '{"int32_values": [1, 2, 3, 4]}', 'int32_values', 'int32[<=3]'),
    (BoundedSequences, '{"int32_values": "abc"}', 'int32_values', 'int32[<=3]'),
    (BoundedSequences, '{"int32_values": {"0": 1}}', 'int32_values', 'int32[<=3]'),
    (BoundedSequences, '{"int32_values": [1, "a"]}', 'int32_values[1]', 'int32'),
    (BoundedSequences, '{"bool_values": [true, 1]}', 'bool_values[1]', 'bool'),
    (BoundedSequences, '{"string_values": [1]}', 'string_values[0]', 'string'),
    (BoundedSequences, '{"basic_types_values": [1]}', 'basic_types_values[0]', 'BasicTypes'),
    (
        BoundedSequences,
        '{"basic_types_values": [{}, {"int8_value": 200}]}',
        'basic_types_values[1].int8_value',
        'int8',
    ),
    (BoundedSequences, '{"basic_types_values": [{}, {}, {}, {}]}', 'basic_types_values', '<=3'),
    (Arrays, '{"int32_values": [1, 2]}', 'int32_values', 'int32[3]'),
    (Arrays, '{"int32_values": [1, 2, 3, 4]}', 'int32_values', 'int32[3]'),
    (Arrays, '{"byte_values": [0, 256, 1]}', 'byte_values[1]', 'byte'),
    (Arrays, '{"uint8_values": "abc"}', 'uint8_values', 'uint8[3]'),
    (Arrays, '{"float32_values": [0, 1, 3.5e38]}', 'float32_values[2]', 'float32'),
    (Arrays, '{"basic_types_values": [{}, {}]}', 'basic_types_values', 'BasicTypes[3]'),
    (Arrays, '{"string_values": ["a", "b", null]}', 'string_values[2]', 'string'),
    (UnboundedSequences, '{"uint8_values": [256]}', 'uint8_values[0]', 'uint8'),
    (UnboundedSequences, '{"byte_values": "AAEC"}', 'byte_values', 'byte[]'),
    (UnboundedSequences, '{"float64_values": [1, null]}', 'float64_values[1]', 'float64'),
    (Nested, '{"basic_types_value": 5}', 'basic_types_value', 'test_msgs/msg/BasicTypes'),
    (Nested, '{"basic_types_value": []}', 'basic_types_value', 'test_msgs/msg/BasicTypes'),
    (
        Nested,
        '{"basic_types_value": {"int32_value": "x"}}',
        'basic_types_value.int32_value',
        'int32',
    ),
    (Builtins, '{"time_value": {"sec": 1.5}}', 'time_value.sec', 'int32'),
    (Builtins, '{"time_value": {"nanosec": -1}}', 'time_value.nanosec', 'uint32'),
    (Builtins, '{"duration_value": null}', 'duration_value', 'builtin_interfaces/msg/Duration'),
    (WStrings, '{"wstring_value": 5}', 'wstring_value', 'wstring'),
    (WStrings, '{"array_of_wstrings": ["a"]}', 'array_of_wstrings', 'wstring[3]'),
    (
        WStrings,
        '{"unbounded_sequence_of_wstrings": [1]}',
        'unbounded_sequence_of_wstrings[0]',
        'wstring',
    ),
    (FakeChars, '{"c": "ab"}', 'c', 'char'),
    (FakeChars, '{"c": "é"}', 'c', 'char'),
    (FakeChars, '{"c": 65}', 'c', 'char'),
    (FakeChars, '{"w": ""}', 'w', 'wchar'),
    (FakeChars, '{"w": "\\udc00"}', 'w', 'wchar'),
    (FakeChars, '{"cs": ["a"]}', 'cs', 'char[2]'),
    (FakeChars, '{"n": 2147483648}', 'n', 'int32'),
    (FakeChars, '{"u": -1}', 'u', 'uint16'),
    (FakeChars, '{"d": "1"}', 'd', 'float64'),
]


@pytest.mark.parametrize(('msg_class', 'text', 'field', 'expected'), BAD_FIELDS)
def test_bad_field_values_name_the_field_and_the_type(
    msg_class: type, text: str, field: str, expected: str
) -> None:
    with pytest.raises(TaskDataError) as caught:
        message_from_json(msg_class, text)
    assert caught.value.field == field
    assert f"field '{field}'" in str(caught.value)
    assert expected in str(caught.value)
    with pytest.raises(TaskDataError):
        message_from_dict(msg_class, json.loads(text))


BAD_TEXTS: list[tuple[str, str]] = [
    ('', 'empty'),
    ('   ', 'empty'),
    ('\n\t ', 'empty'),
    ('not json', 'invalid JSON'),
    ('{', 'invalid JSON'),
    ('{"order": 1,}', 'invalid JSON'),
    ("{'order': 1}", 'invalid JSON'),
    ('{"order": 1} trailing', 'invalid JSON'),
    ('[]', 'JSON object'),
    ('null', 'JSON object'),
    ('1', 'JSON object'),
    ('"x"', 'JSON object'),
    ('true', 'JSON object'),
    ('[{"order": 1}]', 'JSON object'),
    ('{}', 'order'),
    ('{"x": 1}', 'none of the keys'),
    ('{"Order": 1, "ORDER": 2}', 'fields are: order'),
    ('NaN', 'non-finite numbers are not allowed'),
    ('{"order": NaN}', 'non-finite numbers are not allowed'),
    ('{"order": Infinity}', 'non-finite numbers are not allowed'),
    ('{"order": -Infinity}', 'non-finite numbers are not allowed'),
    ('{"order": 1, "extra": NaN}', 'non-finite numbers are not allowed'),
    ('{"order": 1e400}', 'non-finite numbers are not allowed'),
    ('[' * 100_000 + ']' * 100_000, 'nested too deeply'),
    ('{"a":' * 100_000 + '1' + '}' * 100_000, 'nested too deeply'),
    ('{"order": %s}' % ('9' * 5000), 'invalid JSON'),
]


@pytest.mark.parametrize(('text', 'fragment'), BAD_TEXTS)
def test_bad_top_level_text_is_a_task_data_error(text: str, fragment: str) -> None:
    with pytest.raises(TaskDataError) as caught:
        message_from_json(Goal, text)
    assert caught.value.field == ''
    assert fragment in str(caught.value)
    assert len(str(caught.value)) < 300


@pytest.mark.parametrize('text', [None, 5, b'', b'  ', ['{}'], {'order': 1}])
def test_message_from_json_needs_text(text: Any) -> None:
    with pytest.raises(TaskDataError) as caught:
        message_from_json(Goal, text)
    assert caught.value.field == ''


@pytest.mark.parametrize('data', [[], None, 1, 'x', True, ({'order': 1},)])
def test_message_from_dict_needs_a_dict(data: Any) -> None:
    with pytest.raises(TaskDataError, match='JSON object'):
        message_from_dict(Goal, data)


def test_error_message_format() -> None:
    with pytest.raises(TaskDataError) as caught:
        message_from_json(Goal, '{"order": "abc"}')
    assert str(caught.value) == "field 'order': expected int32, got 'abc' (str)"
    with pytest.raises(TaskDataError) as caught:
        message_from_json(Goal, '{"order": 2147483648}')
    assert str(caught.value) == (
        "field 'order': 2147483648 is out of range for int32 [-2147483648, 2147483647]"
    )
    with pytest.raises(TaskDataError) as caught:
        message_from_json(BasicTypes, '{"x": 1}')
    assert 'none of the keys' in str(caught.value)
    assert 'fields are: bool_value, byte_value, char_value' in str(caught.value)


def test_error_is_a_value_error_with_a_short_message() -> None:
    with pytest.raises(ValueError) as caught:
        message_from_json(Goal, json.dumps({'order': 'x' * 100_000}))
    assert isinstance(caught.value, TaskDataError)
    assert len(str(caught.value)) < 150
    with pytest.raises(TaskDataError) as caught:
        message_from_dict(Goal, {'order': [[[[list(range(1000))]]]]})
    assert len(str(caught.value)) < 150


def test_non_finite_values_in_a_dict_are_rejected_at_the_field() -> None:
    for value in (math.nan, math.inf, -math.inf):
        with pytest.raises(TaskDataError, match='non-finite numbers are not allowed') as caught:
            message_from_dict(BasicTypes, {'float64_value': value})
        assert caught.value.field == 'float64_value'


def test_setter_assertions_become_task_data_errors() -> None:
    with pytest.raises(TaskDataError, match='the setter refuses') as caught:
        message_from_dict(Picky, {'value': 1})
    assert caught.value.field == 'value'


# --- accepted input ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ('field', 'low', 'high'),
    [
        ('int8_value', -(2**7), 2**7 - 1),
        ('uint8_value', 0, 2**8 - 1),
        ('int16_value', -(2**15), 2**15 - 1),
        ('uint16_value', 0, 2**16 - 1),
        ('int32_value', -(2**31), 2**31 - 1),
        ('uint32_value', 0, 2**32 - 1),
        ('int64_value', -(2**63), 2**63 - 1),
        ('uint64_value', 0, 2**64 - 1),
        ('byte_value', 0, 255),
    ],
)
def test_integer_limits_are_accepted(field: str, low: int, high: int) -> None:
    for value in (low, high):
        msg = message_from_json(BasicTypes, json.dumps({field: value}))
        assert message_to_dict(msg)[field] == value


def test_float_fields_accept_ints_and_in_range_values() -> None:
    msg = message_from_json(BasicTypes, '{"float64_value": 3, "float32_value": -3.4e38}')
    assert msg.float64_value == 3.0
    assert type(msg.float64_value) is float
    assert msg.float32_value == -3.4e38
    assert message_from_json(BasicTypes, '{"float32_value": 3.4028235e38}').float32_value > 0
    assert message_from_json(BasicTypes, '{"float64_value": 1e308}').float64_value == 1e308


def test_strings_and_bounds() -> None:
    msg = message_from_json(Strings, json.dumps({'bounded_string_value': 'ö' * 22}))
    assert msg.bounded_string_value == 'ö' * 22
    assert message_from_dict(Strings, {'string_value': 'x' * 1_000_000}).string_value[-1] == 'x'
    wide = message_from_json(WStrings, '{"wstring_value": "ハロー 🤖"}')
    assert wide.wstring_value == 'ハロー 🤖'


def test_sequences_at_their_bounds() -> None:
    msg = message_from_json(
        BoundedSequences, '{"int32_values": [1, 2, 3], "byte_values": [0, 255]}'
    )
    assert list(msg.int32_values) == [1, 2, 3]
    assert msg.byte_values == [b'\x00', b'\xff']
    arrays = message_from_json(Arrays, '{"float32_values": [1, 2.5, -3]}')
    assert arrays.float32_values.tolist() == [1.0, 2.5, -3.0]
    unbounded = message_from_dict(UnboundedSequences, {'uint8_values': list(range(256)) * 40})
    assert len(unbounded.uint8_values) == 256 * 40


def test_chars_and_nonexplicit_types() -> None:
    msg = message_from_json(FakeChars, '{"c": "A", "w": "ö", "cs": ["x", "y"], "n": -5, "d": 2}')
    assert (msg.c, msg.w, msg.cs, msg.n, msg.d) == ('A', 'ö', ['x', 'y'], -5, 2.0)
    assert message_to_dict(msg) == {'c': 'A', 'w': 'ö', 'cs': ['x', 'y'], 'n': -5, 'u': 0, 'd': 2.0}


def test_unknown_keys_next_to_known_ones_are_ignored() -> None:
    assert message_from_json(Goal, '{"order": 3, "extra": [1, {"x": null}]}') == Goal(order=3)
    nested = message_from_json(Nested, '{"basic_types_value": {"int8_value": 4, "zzz": 1}, "a": 2}')
    assert nested.basic_types_value.int8_value == 4


def test_nested_empty_or_unknown_object_means_defaults() -> None:
    assert message_from_json(Nested, '{"basic_types_value": {}}') == Nested()
    assert message_from_json(Nested, '{"basic_types_value": {"nope": 1}}') == Nested()
    msg = message_from_json(BoundedSequences, '{"basic_types_values": [{}, {"int8_value": 1}]}')
    assert msg.basic_types_values == [BasicTypes(), BasicTypes(int8_value=1)]


@pytest.mark.parametrize('msg_class', [Empty, Trigger.Request, test_msgs.msg.Constants])
@pytest.mark.parametrize(
    'text', ['{}', '{"anything": 1}', '{"structure_needs_at_least_one_member": 0}']
)
def test_messages_without_fields_accept_any_object(msg_class: type, text: str) -> None:
    assert message_from_json(msg_class, text) == msg_class()
    assert message_to_dict(msg_class()) == {}
    assert message_to_json(msg_class()) == '{}'


def test_missing_fields_keep_the_defaults() -> None:
    msg = message_from_json(Defaults, '{"int8_value": 1}')
    expected = {**message_to_dict(Defaults()), 'int8_value': 1}
    assert message_to_dict(msg) == expected
    strings = message_from_json(Strings, '{"string_value": "a"}')
    assert strings.string_value_default1 == Strings().string_value_default1 != ''


def test_time_and_duration_are_nested_messages() -> None:
    assert message_from_json(Time, '{"sec": 5, "nanosec": 7}') == Time(sec=5, nanosec=7)
    msg = Builtins(time_value=Time(sec=-1, nanosec=2), duration_value=Duration(sec=3, nanosec=4))
    data = message_to_dict(msg)
    assert data == {
        'duration_value': {'sec': 3, 'nanosec': 4},
        'time_value': {'sec': -1, 'nanosec': 2},
    }
    assert message_from_json(Builtins, message_to_json(msg)) == msg


def test_action_and_service_parts_round_trip() -> None:
    feedback = Fibonacci.Impl.FeedbackMessage()
    feedback.feedback.sequence = [1, 1, 2]
    feedback.goal_id.uuid = list(range(16))
    assert message_to_dict(feedback)['feedback'] == {'sequence': [1, 1, 2]}
    assert message_from_json(type(feedback), message_to_json(feedback)) == feedback
    request = Fibonacci.Impl.SendGoalService.Request()
    request.goal.order = 9
    assert message_from_dict(type(request), message_to_dict(request)) == request


def test_generated_setter_checks_pass(monkeypatch: pytest.MonkeyPatch) -> None:
    for msg_class in (BasicTypes, Arrays, BoundedSequences, UnboundedSequences, Strings, Nested):
        module = __import__(msg_class.__module__, fromlist=['_'])
        monkeypatch.setattr(module, 'ros_python_check_fields', '1')
    sample = Arrays(check_fields=False)
    sample.float32_values[0] = 1.5
    sample.byte_values = [b'\x01', b'\x02', b'\x03']
    for msg in (BasicTypes(byte_value=b'\x05'), sample, BoundedSequences(), Strings(), Nested()):
        assert message_from_dict(type(msg), message_to_dict(msg)) == msg


def test_conversion_is_fast() -> None:
    start = time.perf_counter()
    for _ in range(2000):
        message_from_json(Goal, '{"order": 5}')
        message_to_json(Goal(order=5))
    assert time.perf_counter() - start < 1.0
