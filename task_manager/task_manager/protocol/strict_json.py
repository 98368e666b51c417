"""A request's JSON text, read without trusting it: the one reader of every door (the web
gateway's bodies, the MQTT bridge's requests, the VDA 5050 adapter's messages).

Its size and how deep it nests are checked before it is parsed (a parser recurses into each
level: 5,000 levels raise RecursionError), in time linear in its length whatever it holds
(a door runs it before it knows who sent the request), and what Python's parser takes but a
request must not hold is refused: a key twice in one object (the parser keeps the last one,
another reader may keep the first), and NaN, Infinity and numbers too large for a float (not
JSON; the Task Manager would refuse the task later, as task_data_parsing_failed).
"""

import functools
import json
import math
import re
from typing import Any

from task_manager.core.bounds import JSON_MAX_DEPTH, cut_text
from task_manager.protocol.errors import RefusalCode

MAX_DEPTH = JSON_MAX_DEPTH
"""Nesting levels (objects and arrays) a request may have; a mission's task_data uses ~6."""

# every byte but a quote and a bracket (deleted), and the braces as brackets
_NOT_MARK = bytes(b for b in range(256) if b not in b'"[]{}')
_AS_BRACKET = bytes.maketrans(b'{}', b'[]')
_STRING = rb'"[^"]*+"'
"""A string once only quotes and brackets are left: it holds brackets, which do not count."""


class RefusedJsonError(ValueError):
    """JSON text refused; `code` is the protocol's error code for it."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code
        self.message = message


def deeper_than(payload: bytes, levels: int) -> bool:
    """Whether the JSON text `payload` nests objects and arrays deeper than `levels`.

    Linear, without recursion and without a step per byte in Python:

    1. the escapes `\\\\` and `\\"` are taken out, from left to right as a string reads them
       (JSON has no backslash outside a string: a parser stops there, so what follows it
       cannot make the parser recurse);
    2. every byte but the quotes and brackets is deleted, braces become brackets, and two
       quotes side by side are dropped (an empty string, or two strings with nothing between
       them: no bracket changes sides); a string left open runs to the end and is cut;
    3. one regular expression then reads the brackets outside the strings, with a group
       for each level up to `levels`: it fails exactly when a bracket opens deeper.
       A close with nothing open is passed over (a parser stops there too), and closes are
       added at the end so that brackets left open are closed.
    """
    text = payload.replace(b'\\\\', b'').replace(b'\\"', b'')
    marks = text.translate(_AS_BRACKET, _NOT_MARK)
    if marks.count(b'[') <= levels:
        return False
    marks = marks.replace(b'""', b'')
    if marks.count(b'"') % 2:
        marks = marks[: marks.rindex(b'"')]
    return _nested_within(levels).fullmatch(marks + b']' * (levels + 1)) is None


@functools.cache
def _nested_within(levels: int) -> re.Pattern[bytes]:
    """Brackets and strings (step 3 of deeper_than), the brackets `levels` deep at most."""
    content = _STRING  # what the deepest group may hold
    for _ in range(levels):
        group = rb'\[(?:' + content + rb')*+\]'
        content = group + b'|' + _STRING
    return re.compile(rb'(?:' + content + rb'|\]++)*+')


def load_within(payload: bytes, max_depth: int = MAX_DEPTH) -> Any:
    """The JSON document in `payload` as Python's parser reads it (a key twice, NaN), but only
    when it nests at most `max_depth` levels (a parser recurses into each); ValueError for
    anything else. For the documents of a trusted writer (what a robot's bridge publishes,
    read by a FleetClient); a request is read by `load`."""
    if deeper_than(payload, max_depth):
        raise ValueError(f'nested deeper than {max_depth} levels')
    return json.loads(payload)


def load(payload: bytes, max_depth: int = MAX_DEPTH, max_bytes: int | None = None) -> Any:
    """The document in `payload`; RefusedJsonError for anything not plain JSON of at most
    `max_bytes` bytes (None: any size) and `max_depth` levels, with a duplicate key or a
    number that is not finite."""
    if max_bytes is not None and len(payload) > max_bytes:
        message = f'the request is {len(payload)} bytes; at most {max_bytes} allowed'
        raise RefusedJsonError(RefusalCode.PAYLOAD_TOO_LARGE, message)
    if deeper_than(payload, max_depth):
        raise RefusedJsonError(
            RefusalCode.NESTING_TOO_DEEP,
            f'the request nests deeper than {max_depth} levels; at most {max_depth} allowed',
        )
    try:
        text = payload.decode()
    except UnicodeDecodeError as error:
        message = f'not UTF-8 text: byte 0x{payload[error.start]:02x} at offset {error.start}'
        raise RefusedJsonError(RefusalCode.INVALID_REQUEST, message) from None
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
        raise RefusedJsonError(RefusalCode.INVALID_REQUEST, message) from None
    except ValueError as error:  # an integer of more digits than Python converts (4,300)
        raise RefusedJsonError(RefusalCode.INVALID_REQUEST, f'not valid JSON: {error}') from None


def _without_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    document: dict[str, Any] = {}
    for key, value in pairs:
        if key in document:
            raise RefusedJsonError(
                RefusalCode.INVALID_REQUEST,
                f'the key {cut_text(key)!r} is given twice in one object',
            )
        document[key] = value
    return document


def _no_constant(name: str) -> Any:
    raise RefusedJsonError(
        RefusalCode.INVALID_REQUEST, f'{name} is not a JSON number: numbers must be finite'
    )


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise RefusedJsonError(
            RefusalCode.INVALID_REQUEST, f'{text[:40]} is too large for a number here'
        )
    return value
