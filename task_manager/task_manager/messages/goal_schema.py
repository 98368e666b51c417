"""A JSON Schema (2020-12) of a ROS message class: what its task_data may hold.

Generated from the class's own introspection, like json_codec (whose rules it states):
field names, types and bounds, defaults, nested messages and arrays. Unknown keys are
allowed (the node ignores them); the top-level object must name at least one field.
"""

import importlib
from typing import Any

from rosidl_parser import definition as idl

from task_manager.core.task_spec import TaskKind, parse_interface_name
from task_manager.messages.json_codec import (
    HIDDEN_MEMBER,
    TYPE_ALIASES,
    import_class,
    int_range,
    message_to_dict,
    ros_name,
)

JSON_SCHEMA_DIALECT = 'https://json-schema.org/draft/2020-12/schema'
_FLOAT32_MAX = 3.4028235e38
_INTEGERS = {f'{u}int{bits}' for bits in (8, 16, 32, 64) for u in ('', 'u')}


def goal_schema(msg_class: type) -> dict[str, Any]:
    """The JSON Schema of task_data for a goal or request class (a top-level document)."""
    schema = _message_schema(msg_class)
    required_one = [{'required': [name]} for name in schema['properties']]
    return {
        '$schema': JSON_SCHEMA_DIALECT,
        **schema,
        **({'anyOf': required_one} if required_one else {}),
    }


def _message_schema(msg_class: type) -> dict[str, Any]:
    defaults = message_to_dict(msg_class())
    names = msg_class.get_fields_and_field_types()  # type: ignore[attr-defined]
    slots = msg_class.SLOT_TYPES  # type: ignore[attr-defined]
    properties = {
        name: {**_slot_schema(slot), 'default': defaults.get(name)}
        for name, slot in zip(names, slots, strict=True)
        if name != HIDDEN_MEMBER
    }
    return {
        'type': 'object',
        'title': _message_name(msg_class),
        'properties': properties,
        'additionalProperties': True,
    }


def _message_name(msg_class: type) -> str:
    parts = msg_class.__module__.split('.')
    return '/'.join([*parts[:2], msg_class.__name__]) if len(parts) > 2 else msg_class.__name__


def _slot_schema(slot: idl.AbstractType) -> dict[str, Any]:
    """The schema of one field; `x-ros-type` keeps its ROS type (e.g. float64[3])."""
    return {**_value_schema(slot), 'x-ros-type': ros_name(slot)}


def _value_schema(slot: idl.AbstractType) -> dict[str, Any]:
    if isinstance(slot, idl.NamespacedType):
        return _message_schema(import_class(slot))
    if isinstance(slot, idl.AbstractNestedType):
        return _array_schema(slot)
    if isinstance(slot, idl.AbstractGenericString):
        if isinstance(slot, idl.BoundedString | idl.BoundedWString):
            return {'type': 'string', 'maxLength': slot.maximum_size}
        return {'type': 'string'}
    if isinstance(slot, idl.BasicType):
        return _basic_schema(slot.typename)
    raise TypeError(f'unsupported ROS field type {slot!r}')


def _array_schema(slot: idl.AbstractNestedType) -> dict[str, Any]:
    schema: dict[str, Any] = {'type': 'array', 'items': _value_schema(slot.value_type)}
    if isinstance(slot, idl.Array):
        schema.update(minItems=slot.size, maxItems=slot.size)
    elif isinstance(slot, idl.BoundedSequence):
        schema['maxItems'] = slot.maximum_size
    return schema


def _basic_schema(typename: str) -> dict[str, Any]:
    name = TYPE_ALIASES.get(typename, typename)
    if name in _INTEGERS:
        low, high = int_range(name)
        return {'type': 'integer', 'minimum': low, 'maximum': high}
    if name == 'byte':
        return {'type': 'integer', 'minimum': 0, 'maximum': 255}
    if name == 'float32':
        return {'type': 'number', 'minimum': -_FLOAT32_MAX, 'maximum': _FLOAT32_MAX}
    if name == 'float64':
        return {'type': 'number'}
    if name == 'bool':
        return {'type': 'boolean'}
    if name in ('char', 'wchar'):
        return {'type': 'string', 'minLength': 1, 'maxLength': 1}
    raise TypeError(f'unsupported ROS basic type {typename!r}')


def task_data_schema(msg_interface: str) -> dict[str, Any]:
    """The goal_schema of an action's Goal or a service's Request (`pkg/action/Name`, ...).

    ImportError when the interface is not installed here, ConfigurationError for a malformed
    name.
    """
    name = parse_interface_name(msg_interface)
    interface = getattr(importlib.import_module(f'{name.package}.{name.kind}'), name.name, None)
    if interface is None:
        raise ImportError(f'{name} is not in {name.package}.{name.kind}')
    return goal_schema(interface.Goal if name.kind is TaskKind.ACTION else interface.Request)
