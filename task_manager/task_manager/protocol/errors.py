"""A pydantic validation error as the protocol's error: one message and the field at fault."""

from collections.abc import Iterable, Sequence
from typing import Any

MAX_ERRORS_SHOWN = 5


def field_of(location: Iterable[Any], skip: Sequence[str] = ()) -> str:
    """A dotted field path from a pydantic error location, without the parts in `skip`."""
    return '.'.join(str(part) for part in location if part not in skip)


def _message(error: Any, skip: Sequence[str]) -> str:
    field = field_of(error.get('loc', ()), skip)
    message = str(error.get('msg', 'invalid'))
    kind = error.get('type')
    if kind == 'extra_forbidden':
        message = 'unknown field (see the schema for the fields allowed)'
    if kind in ('model_attributes_type', 'dict_type') and not field:
        return 'the message must be a JSON object'
    if kind == 'json_invalid':
        context = error.get('ctx') or {}
        return f'not valid JSON: {context.get("error", message)}'
    if kind == 'union_tag_not_found':
        return f'{field}: missing field "op"' if field else 'missing field "op"'
    return f'{field}: {message}' if field else message


def describe(errors: Sequence[Any], skip: Sequence[str] = ()) -> tuple[str, str]:
    """(message, field) of pydantic's `errors()`: the first few joined, the first one's field.

    `skip`: location parts that name no field (e.g. 'body', or a union's tag).
    """
    first = errors[0] if errors else {}
    message = '; '.join(_message(each, skip) for each in errors[:MAX_ERRORS_SHOWN])
    # the location of invalid JSON is a character offset, not a field
    field = '' if first.get('type') == 'json_invalid' else field_of(first.get('loc', ()), skip)
    return message or 'invalid request', field
