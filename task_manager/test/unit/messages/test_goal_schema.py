"""The JSON Schema of a task's goal, generated from its ROS interface, says what the node takes."""

from typing import Any

import jsonschema
import pytest
from test_msgs.action import Fibonacci
from test_msgs.msg import Arrays, BasicTypes, BoundedSequences, Nested, Strings

from task_manager.core.errors import ConfigurationError
from task_manager.messages.goal_schema import goal_schema, task_data_schema
from task_manager.messages.json_codec import TaskDataError, message_from_dict, message_to_dict

CLASSES = [BasicTypes, Arrays, BoundedSequences, Nested, Strings, Fibonacci.Goal]


@pytest.mark.parametrize('msg_class', CLASSES, ids=lambda c: c.__name__)
def test_a_schema_is_valid_and_takes_the_message_defaults(msg_class: type) -> None:
    schema = goal_schema(msg_class)

    jsonschema.Draft202012Validator.check_schema(schema)
    jsonschema.validate(message_to_dict(msg_class()), schema)


def test_types_bounds_and_defaults_come_from_the_interface() -> None:
    basic = goal_schema(BasicTypes)['properties']
    arrays = goal_schema(Arrays)['properties']
    bounded = goal_schema(BoundedSequences)['properties']
    strings = goal_schema(Strings)['properties']

    assert basic['int8_value'] | {'default': 0} == {
        'type': 'integer', 'minimum': -128, 'maximum': 127, 'x-ros-type': 'int8', 'default': 0,
    }  # fmt: skip
    assert basic['uint64_value']['maximum'] == 2**64 - 1
    assert basic['bool_value']['type'] == 'boolean'
    assert (basic['byte_value']['minimum'], basic['byte_value']['maximum']) == (0, 255)
    assert (arrays['int32_values']['minItems'], arrays['int32_values']['maxItems']) == (3, 3)
    assert arrays['basic_types_values']['items']['properties']['float64_value']['type'] == 'number'
    assert bounded['int32_values']['maxItems'] == 3 and 'minItems' not in bounded['int32_values']
    assert strings['bounded_string_value']['maxLength'] == 22
    assert strings['string_value_default1']['default'] == 'Hello world!'


def test_nested_messages_are_nested_objects() -> None:
    nested = goal_schema(Nested)['properties']['basic_types_value']

    assert nested['type'] == 'object'
    assert nested['title'] == 'test_msgs/msg/BasicTypes'
    assert nested['properties']['int16_value']['minimum'] == -(2**15)


@pytest.mark.parametrize(
    'data',
    [
        {'int8_value': 128},
        {'uint8_value': -1},
        {'bool_value': 1},
        {'char_value': 'ab'},
        {'string_value': 5},
        {},
    ],
)
def test_what_the_schema_refuses_the_node_refuses_too(data: dict[str, Any]) -> None:
    schema = goal_schema(BasicTypes)

    assert not jsonschema.Draft202012Validator(schema).is_valid(data)
    with pytest.raises(TaskDataError):
        message_from_dict(BasicTypes, data)


def test_an_interface_name_in_either_form_gives_its_goal_or_request() -> None:
    assert (
        task_data_schema('test_msgs/action/Fibonacci')['title'] == 'test_msgs/action/Fibonacci_Goal'
    )
    assert task_data_schema('std_srvs.srv.SetBool')['properties']['data']['type'] == 'boolean'
    with pytest.raises(ImportError):
        task_data_schema('test_msgs/action/NoSuchAction')
    with pytest.raises(ConfigurationError):
        task_data_schema('not an interface')
