"""A request's JSON text, read without trusting it.

How deep it nests is checked before it is parsed (a parser recurses into each level: 5,000
levels raise RecursionError), and what Python's parser takes but a request must not hold is
refused: a key twice in one object (the parser keeps the last one, another reader may keep
the first), and NaN, Infinity and numbers too large for a float (not JSON; the Task Manager
would refuse the task later, as task_data_parsing_failed).
"""

import json
import math
import re
from itertools import accumulate
from typing import Any

MAX_DEPTH = 32
"""Nesting levels (objects and arrays) a request may have; a mission's task_data uses ~6."""

_STRING = re.compile(rb'"[^"\\]*(?:\\.[^"\\]*)*"', re.DOTALL)
_NOT_BRACKET = re.compile(rb'[^\[\]{}]+')
# key: byte, value: its step in nesting depth
_DEPTH_STEP = tuple(1 if b in b'[{' else -1 if b in b']}' else 0 for b in range(256))


class RefusedJsonError(ValueError):
    """JSON text refused; `code` is the protocol's error code for it."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code
        self.message = message


def deeper_than(payload: bytes, levels: int) -> bool:
    """Whether the JSON text `payload` nests objects and arrays deeper than `levels`.

    Linear, without recursion: strings are skipped (brackets in them do not count), then
    the depth is the highest running sum of +1 per opening and -1 per closing bracket.
    """
    brackets = _NOT_BRACKET.sub(b'', _STRING.sub(b'', payload))
    if len(brackets) <= levels:
        return False
    return max(accumulate(map(_DEPTH_STEP.__getitem__, brackets))) > levels


def load(payload: bytes, max_depth: int = MAX_DEPTH) -> Any:
    """The document in `payload`; RefusedJsonError for anything not plain JSON of at most
    `max_depth` levels, with a duplicate key or a number that is not finite."""
    if deeper_than(payload, max_depth):
        raise RefusedJsonError(
            'nesting_too_deep',
            f'the request nests deeper than {max_depth} levels; at most {max_depth} allowed',
        )
    try:
        text = payload.decode()
    except UnicodeDecodeError as error:
        message = f'not UTF-8 text: byte 0x{payload[error.start]:02x} at offset {error.start}'
        raise RefusedJsonError('invalid_request', message) from None
    try:
        return json.loads(
            text,
            object_pairs_hook=_without_duplicates,
            parse_constant=_no_constant,
            parse_float=_finite_float,
        )
    except RefusedJsonError:
        raise
    except json.JSONDecodeError as error:
        message = f'not valid JSON: {error.msg} (line {error.lineno}, column {error.colno})'
        raise RefusedJsonError('invalid_request', message) from None
    except ValueError as error:  # an integer of more digits than Python converts (4,300)
        raise RefusedJsonError('invalid_request', f'not valid JSON: {error}') from None


def _without_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    document: dict[str, Any] = {}
    for key, value in pairs:
        if key in document:
            raise RefusedJsonError(
                'invalid_request', f'the key {key!r} is given twice in one object'
            )
        document[key] = value
    return document


def _no_constant(name: str) -> Any:
    raise RefusedJsonError(
        'invalid_request', f'{name} is not a JSON number: numbers must be finite'
    )


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise RefusedJsonError('invalid_request', f'{text[:40]} is too large for a number here')
    return value
