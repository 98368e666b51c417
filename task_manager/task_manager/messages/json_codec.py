"""Convert between JSON task data and ROS 2 messages using only the classes' own introspection.

Choices made here (beyond the behaviour spec):

- ``char`` fields take a one-character ASCII string (rosidl stores char as a 1-char ``str``);
  ``wchar`` fields take one character of the Basic Multilingual Plane other than a surrogate.
- ``byte``/``octet`` fields take an int 0..255; sequences of them a list of such ints (no base64).
- Bounded string bounds count characters, as the generated setters do.
- Strings that cannot be encoded (unpaired surrogates such as ``"\\ud800"``) are rejected.
- Only the top-level object must name at least one field; a nested ``{}`` (or a nested object
  with only unknown keys) means the nested message's defaults. Unknown keys are ignored.
- Non-finite numbers (``NaN``, ``Infinity``, literals such as ``1e400``) are rejected anywhere in
  JSON text; ``message_to_dict`` keeps them as floats and ``message_to_json`` writes them as null.
"""

import array
import importlib
import json
import math
import re
import reprlib
import sys
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache, partial
from types import ModuleType
from typing import Any, TypeVar, cast

import numpy
from rosidl_parser import definition as idl

from task_manager.core.text.json_text import compact_json

T = TypeVar('T')
Decoder = Callable[[Any, str], Any]
Encoder = Callable[[Any], Any]

HIDDEN_MEMBER = 'structure_needs_at_least_one_member'
_FLOAT_BOUNDS = {'float32': 3.4028235e38, 'float64': sys.float_info.max}
TYPE_ALIASES = {
    'short': 'int16',
    'unsigned short': 'uint16',
    'long': 'int32',
    'unsigned long': 'uint32',
    'long long': 'int64',
    'unsigned long long': 'uint64',
    'float': 'float32',
    'double': 'float64',
    'long double': 'float64',
    'boolean': 'bool',
    'octet': 'byte',
}
# Element types rosidl keeps in numpy arrays (Array) or array.array (sequences), by type code.
_NUMERIC = ('float', 'double', *(f'{u}int{bits}' for bits in (8, 16, 32, 64) for u in ('', 'u')))
_TYPE_CODES = dict(zip(_NUMERIC, 'fdbBhHiIqQ', strict=True))
_SHOW_LIMIT = 60
_REPR = reprlib.Repr()
_REPR.maxstring = _SHOW_LIMIT
_REPR.maxother = _SHOW_LIMIT
_REPR.maxlong = _SHOW_LIMIT
_REPR.maxlevel = 3
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = 6


class TaskDataError(ValueError):
    """task_data cannot become the message: names the field, the value given and what it expects."""

    def __init__(self, field: str, problem: str, result: dict[str, Any] | None = None) -> None:
        """Record ``field`` (a dotted path, '' for the top level) and describe the problem.

        ``result`` is what the requester gets besides the error (e.g. a mission's rows).
        """
        self.field = field
        self.result = result or {}
        super().__init__(f"field '{field}': {problem}" if field else f'task_data: {problem}')


@dataclass(frozen=True, slots=True)
class _Field:
    """How one message field is named, decoded from JSON and encoded back."""

    name: str
    ros_type: str
    decode: Decoder
    encode: Encoder


def _show(value: Any) -> str:
    """Return a short repr of ``value`` for error messages."""
    try:
        text = _REPR.repr(value)
    except Exception:
        text = f'<{type(value).__name__}>'
    return text if len(text) <= _SHOW_LIMIT else text[: _SHOW_LIMIT - 3] + '...'


def _expected(path: str, expected: str, value: Any) -> TaskDataError:
    """Build the error for a value of the wrong type."""
    return TaskDataError(path, f'expected {expected}, got {_show(value)} ({type(value).__name__})')


def _snake(name: str) -> str:
    """Convert a CamelCase interface name to the module name rosidl generates for it."""
    name = re.sub(r'(.)([A-Z][a-z]+)', r'\1_\2', name)
    return re.sub(r'([a-z0-9])([A-Z])', r'\1_\2', name).lower()


def import_class(slot: idl.NamespacedType) -> type:
    """Import the message class of a nested type, e.g. builtin_interfaces.msg.Time."""
    package: ModuleType = importlib.import_module('.'.join(slot.namespaces))
    if hasattr(package, slot.name):
        return cast(type, getattr(package, slot.name))
    module = importlib.import_module(f'{package.__name__}._{_snake(slot.name.split("_")[0])}')
    return cast(type, getattr(module, slot.name))


def _class_name(msg_class: type) -> str:
    """Return the ROS name of a message class, e.g. builtin_interfaces/msg/Time."""
    parts = msg_class.__module__.split('.')
    return '/'.join([*parts[:2], msg_class.__name__]) if len(parts) > 2 else msg_class.__qualname__


def ros_name(slot: idl.AbstractType) -> str:
    """Return the ROS name of a field type, e.g. int32, string<=10, float64[3], pkg/msg/T[]."""
    if isinstance(slot, idl.BasicType):
        return TYPE_ALIASES.get(slot.typename, slot.typename)
    if isinstance(slot, idl.NamespacedType):
        return '/'.join(slot.namespaced_name())
    if isinstance(slot, idl.AbstractGenericString):
        base = 'wstring' if isinstance(slot, idl.AbstractWString) else 'string'
        if isinstance(slot, idl.BoundedString | idl.BoundedWString):
            return f'{base}<={slot.maximum_size}'
        return base
    if isinstance(slot, idl.Array):
        return f'{ros_name(slot.value_type)}[{slot.size}]'
    if isinstance(slot, idl.BoundedSequence):
        return f'{ros_name(slot.value_type)}[<={slot.maximum_size}]'
    if isinstance(slot, idl.UnboundedSequence):
        return f'{ros_name(slot.value_type)}[]'
    raise TypeError(f'unsupported ROS field type {slot!r}')


def int_range(name: str) -> tuple[int, int]:
    """The lowest and highest value of the integer type ``name`` (e.g. int8: -128, 127)."""
    bits = int(name.lstrip('uint'))
    if name.startswith('u'):
        return 0, 2**bits - 1
    return -(2 ** (bits - 1)), 2 ** (bits - 1) - 1


def _int_decoder(name: str) -> Decoder:
    """Decode a JSON integer (not bool, not float) within the range of ``name``."""
    low, high = int_range(name)

    def decode(value: Any, path: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise _expected(path, name, value)
        if not low <= value <= high:
            raise TaskDataError(path, f'{_show(value)} is out of range for {name} [{low}, {high}]')
        return int(value)

    return decode


def _float_decoder(name: str) -> Decoder:
    """Decode a finite JSON number that fits ``name`` (float32 or float64)."""
    bound = _FLOAT_BOUNDS[name]

    def decode(value: Any, path: str) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise _expected(path, name, value)
        if isinstance(value, float) and not math.isfinite(value):
            raise TaskDataError(path, f'non-finite numbers are not allowed, got {value} for {name}')
        if abs(value) > bound:
            raise TaskDataError(path, f'{_show(value)} is out of range for {name} (±{bound})')
        return float(value)

    return decode


def _decode_bool(value: Any, path: str) -> bool:
    """Decode JSON true/false."""
    if not isinstance(value, bool):
        raise _expected(path, 'bool (true or false)', value)
    return value


def _decode_byte(value: Any, path: str) -> bytes:
    """Decode an int 0..255 into the 1-byte bytes rosidl uses for byte/octet."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 255:
        raise _expected(path, 'byte (an integer 0..255)', value)
    return bytes((value,))


def _char_decoder(name: str) -> Decoder:
    """Decode a one-character string: ASCII for char, non-surrogate for wchar."""
    limit = 128 if name == 'char' else 0x10000

    def decode(value: Any, path: str) -> str:
        if not (isinstance(value, str) and len(value) == 1 and ord(value) < limit):
            kind = 'ASCII character' if name == 'char' else 'character'
            raise _expected(path, f'{name} (a one-{kind} string)', value)
        if 0xD800 <= ord(value) < 0xE000:
            raise TaskDataError(path, f'{_show(value)} is an unpaired surrogate, not a {name}')
        return value

    return decode


def _string_decoder(name: str, bound: int | None) -> Decoder:
    """Decode an encodable JSON string no longer than ``bound`` characters."""

    def decode(value: Any, path: str) -> str:
        if not isinstance(value, str):
            raise _expected(path, name, value)
        try:
            value.encode('utf-8')
        except UnicodeEncodeError as exc:
            raise TaskDataError(path, f'{name} contains an unpaired surrogate') from exc
        if bound is not None and len(value) > bound:
            raise TaskDataError(path, f'{_show(value)} is longer than {name} ({len(value)} chars)')
        return value

    return decode


def _basic_decoder(name: str) -> Decoder:
    """Return the decoder of a basic type given by its ROS name."""
    if name in _FLOAT_BOUNDS:
        return _float_decoder(name)
    if name in ('char', 'wchar'):
        return _char_decoder(name)
    return {'bool': _decode_bool, 'byte': _decode_byte}.get(name) or _int_decoder(name)


def _sequence_decoder(slot: idl.AbstractNestedType, element: Decoder) -> Decoder:
    """Decode a JSON array of the right length into the container rosidl uses."""
    name = ros_name(slot)
    size = slot.size if isinstance(slot, idl.Array) else None
    limit = slot.maximum_size if isinstance(slot, idl.BoundedSequence) else None
    typename = getattr(slot.value_type, 'typename', None)
    build: Callable[[list[Any]], Any] = list
    if typename in _TYPE_CODES:
        code = _TYPE_CODES[typename]
        build = (
            partial(numpy.array, dtype=numpy.dtype(code)) if size else partial(array.array, code)
        )

    def decode(value: Any, path: str) -> Any:
        if not isinstance(value, list | tuple):
            raise _expected(path, f'{name} (a JSON array)', value)
        count = len(value)
        if size is not None and count != size:
            raise TaskDataError(path, f'expected {name}: exactly {size} elements, got {count}')
        if limit is not None and count > limit:
            raise TaskDataError(path, f'expected {name}: at most {limit} elements, got {count}')
        return build([element(item, f'{path}[{i}]') for i, item in enumerate(value)])

    return decode


def _decoder(slot: idl.AbstractType) -> Decoder:
    """Return the JSON decoder for a field type."""
    if isinstance(slot, idl.AbstractNestedType):
        return _sequence_decoder(slot, _decoder(slot.value_type))
    if isinstance(slot, idl.NamespacedType):
        return partial(_from_dict, import_class(slot))
    if isinstance(slot, idl.BoundedString | idl.BoundedWString):
        return _string_decoder(ros_name(slot), int(slot.maximum_size))
    if isinstance(slot, idl.AbstractGenericString):
        return _string_decoder(ros_name(slot), None)
    return _basic_decoder(ros_name(slot))


def _encode_scalar(value: Any) -> Any:
    """Return a basic field value as a plain Python value."""
    return value.item() if isinstance(value, numpy.generic) else value


def _encode_byte(value: Any) -> int:
    """Return a byte/octet value (1-byte bytes) as an int."""
    return value[0] if isinstance(value, bytes | bytearray) else int(value)


def _sequence_encoder(element: Encoder) -> Encoder:
    """Return an encoder of lists, array.array, numpy arrays and bytes into plain lists."""

    def encode(value: Any) -> list[Any]:
        if isinstance(value, numpy.ndarray | array.array):
            return value.tolist()
        if isinstance(value, bytes | bytearray):
            return list(value)
        return [element(item) for item in value]

    return encode


def _encoder(slot: idl.AbstractType) -> Encoder:
    """Return the plain-value encoder for a field type."""
    if isinstance(slot, idl.AbstractNestedType):
        return _sequence_encoder(_encoder(slot.value_type))
    if isinstance(slot, idl.NamespacedType):
        return message_to_dict
    if isinstance(slot, idl.BasicType) and slot.typename == 'octet':
        return _encode_byte
    return _encode_scalar


@cache
def _fields(msg_class: type) -> tuple[_Field, ...]:
    """Return the cached field codecs of a message class, in declaration order."""
    try:
        names = msg_class.get_fields_and_field_types()  # type: ignore[attr-defined]
        slots = msg_class.SLOT_TYPES  # type: ignore[attr-defined]
    except AttributeError as exc:
        raise TypeError(f'{msg_class!r} is not a ROS 2 message class') from exc
    return tuple(
        _Field(name, ros_name(slot), _decoder(slot), _encoder(slot))
        for name, slot in zip(names, slots, strict=True)
        if name != HIDDEN_MEMBER
    )


def _check_known_keys(msg_class: type, fields: tuple[_Field, ...], data: dict[Any, Any]) -> None:
    """Reject a top-level object that names none of the message's fields."""
    if not fields or any(field.name in data for field in fields):
        return
    names = ', '.join(field.name for field in fields)
    if not data:
        raise TaskDataError('', f'empty object; {_class_name(msg_class)} has fields: {names}')
    keys = _show(list(data))
    raise TaskDataError(
        '', f'none of the keys {keys} is a field of {_class_name(msg_class)}; fields are: {names}'
    )


def _from_dict(msg_class: type[T], data: Any, path: str) -> T:
    """Build a ``msg_class`` instance from ``data`` found at ``path``."""
    if not isinstance(data, dict):
        raise _expected(path, f'{_class_name(msg_class)} (a JSON object)', data)
    fields = _fields(msg_class)  # type: ignore[arg-type]  # classes are Hashable (mypy#11470)
    if not path:
        _check_known_keys(msg_class, fields, data)
    msg = msg_class()
    for field in fields:
        if field.name in data:
            field_path = f'{path}.{field.name}' if path else field.name
            value = field.decode(data[field.name], field_path)
            try:
                setattr(msg, field.name, value)
            except (AssertionError, TypeError, ValueError, OverflowError) as exc:
                raise TaskDataError(field_path, f'expected {field.ros_type}: {exc}') from exc
    return msg


def _parse_float(token: str) -> float:
    """Parse a number literal, refusing NaN, Infinity and ones too large to be finite (1e400)."""
    value = float(token)
    if not math.isfinite(value):
        raise TaskDataError('', f'non-finite numbers are not allowed, got {_show(token)}')
    return value


def parse_json_text(text: str) -> Any:
    """Parse JSON text, turning every failure into TaskDataError."""
    if not isinstance(text, str | bytes | bytearray):
        raise _expected('', 'JSON text (str)', text)
    if not text.strip():
        raise TaskDataError('', 'empty text; expected a JSON object')
    try:
        return json.loads(text, parse_constant=_parse_float, parse_float=_parse_float)
    except TaskDataError:
        raise
    except json.JSONDecodeError as exc:
        raise TaskDataError('', f'invalid JSON: {exc}') from None
    except RecursionError:
        raise TaskDataError('', 'invalid JSON: nested too deeply') from None
    except Exception as exc:
        raise TaskDataError('', f'invalid JSON: {str(exc)[:200]}') from None


def message_from_json(msg_class: type[T], text: str) -> T:
    """Build a ``msg_class`` instance from JSON text holding an object of its fields."""
    return message_from_dict(msg_class, parse_json_text(text))


def message_from_dict(msg_class: type[T], data: dict[str, Any]) -> T:
    """Build a ``msg_class`` instance from a dict of its fields; missing fields keep defaults."""
    if not isinstance(data, dict):
        raise _expected('', f'a JSON object for {_class_name(msg_class)}', data)
    return _from_dict(msg_class, data, '')


def message_to_dict(msg: Any) -> dict[str, Any]:
    """Return every field of ``msg`` by name, in declaration order, as plain Python values."""
    fields = _fields(type(msg))  # type: ignore[arg-type]  # classes are Hashable (mypy#11470)
    return {field.name: field.encode(getattr(msg, field.name)) for field in fields}


def dict_to_json(data: dict[str, Any]) -> str:
    """Compact JSON of a message's dict (see message_to_dict); NaN and infinities become null."""
    return compact_json(data)


def message_to_json(msg: Any) -> str:
    """Return ``msg`` as compact JSON; NaN and infinities are written as null."""
    return dict_to_json(message_to_dict(msg))
