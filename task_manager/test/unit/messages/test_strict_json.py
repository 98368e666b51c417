"""The one reader of every door's JSON (protocol/strict_json.py): its depth check agrees with
a parser on any JSON, never lets a parser recurse deeper than it says, and takes linear time
on any input up to the gateways' largest body (issue 37, item 4: escaped quotes made the
check of old quadratic, 36 s for 128 kB)."""

import json
import time
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from task_manager.core.bounds import JSON_MAX_DEPTH, TASK_DATA_MAX_BYTES
from task_manager.protocol.strict_json import RefusedJsonError, deeper_than, load, load_within

LIMIT = TASK_DATA_MAX_BYTES
CHECK_MAX_SEC = 0.050
"""The most one check of a body up to the limit may take (it takes at most ~25 ms here)."""

# strings made of what matters to the check: quotes, backslashes, brackets
tricky_text = st.text(alphabet='"\\[]{}a\u00e9', max_size=8)
json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | tricky_text,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(tricky_text, inner, max_size=4),
    max_leaves=40,
)
# any JSON Python writes, NaN and infinities included (what a FleetClient may receive)
any_json = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=10), inner),
    max_leaves=30,
)


def depth_of(value: Any) -> int:
    """Nesting levels of a parsed document, without recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict | list):
            depth += 1
            deepest = max(deepest, depth)
            stack.extend(
                (child, depth) for child in (item.values() if isinstance(item, dict) else item)
            )
    return deepest


def depth_a_parser_reaches(payload: bytes) -> int:
    """The deepest level a JSON parser can open in `payload` before it must stop: at a
    backslash outside a string or a close with nothing open (a reference, byte by byte)."""
    depth = deepest = 0
    in_string = escaped = False
    for byte in payload:
        character = chr(byte)
        if in_string:
            if escaped:
                escaped = False
            elif character == '\\':
                escaped = True
            elif character == '"':
                in_string = False
        elif character == '"':
            in_string = True
        elif character == '\\':
            break
        elif character in '[{':
            depth += 1
            deepest = max(deepest, depth)
        elif character in ']}':
            if depth == 0:
                break
            depth -= 1
    return deepest


@settings(max_examples=400, deadline=None)
@given(value=json_values, levels=st.integers(0, 6), ascii_only=st.booleans())
def test_the_depth_check_agrees_with_the_parsed_document(
    value: Any, levels: int, ascii_only: bool
) -> None:
    text = json.dumps(value, ensure_ascii=ascii_only).encode()

    assert deeper_than(text, levels) == (depth_of(value) > levels), text


@settings(max_examples=400, deadline=None)
@given(
    payload=st.lists(st.sampled_from([b'[', b']', b'{', b'}', b'"', b'\\', b'a', b','])).map(
        b''.join
    ),
    levels=st.integers(0, 5),
)
def test_what_the_check_lets_through_never_nests_deeper_for_a_parser(
    payload: bytes, levels: int
) -> None:
    if not deeper_than(payload, levels):
        assert depth_a_parser_reaches(payload) <= levels, payload


@settings(max_examples=100, deadline=None)
@given(value=any_json)
def test_the_fleet_client_reads_any_json_within_the_depth(value: Any) -> None:
    text = json.dumps(value).encode()
    if depth_of(value) > JSON_MAX_DEPTH:
        with pytest.raises(ValueError, match='nested deeper than 32 levels'):
            load_within(text)
    else:
        assert json.dumps(load_within(text)) == text.decode()  # (NaN is not equal to itself)


def repeated(unit: bytes, head: bytes = b'', tail: bytes = b'') -> bytes:
    """`head`, then `unit` as many times as fit in LIMIT bytes with `tail`, then `tail`."""
    return head + unit * ((LIMIT - len(head) - len(tail)) // len(unit)) + tail


# each: a body of LIMIT bytes (or just under: its unit did not fit once more), and whether it
# nests deeper than 32 levels
ADVERSARIAL = {
    'escaped quotes, left open': (repeated(b'\\"', b'"'), False),
    'escaped quotes, closed': (repeated(b'\\"', b'"', b'"'), False),
    'escaped quotes in an object': (repeated(b'\\"', b'{"a": "', b'"}'), False),
    'quotes': (repeated(b'"'), False),
    'backslashes': (repeated(b'\\'), False),
    'a quote and backslashes': (repeated(b'\\', b'"'), False),
    'escaped backslashes, then brackets': (repeated(b'\\\\', b'"', b'"' + b'[' * 40), True),
    'openings': (repeated(b'['), True),
    'braces and brackets': (repeated(b'{"a":['), True),
    'closings': (repeated(b']'), False),
    'pairs': (repeated(b'[]'), False),
    'towers of 32': (repeated(b'[' * 32 + b']' * 32), False),
    'towers of 33': (repeated(b'[' * 33 + b']' * 33), True),
    'level 31, then pairs': (repeated(b'[]', b'[' * 31, b']' * 31), False),
    'brackets in strings': (repeated(b'"[{",', b'['), False),
    'brackets in and out of strings': (repeated(b'"[]",[],'), False),
    'a string and brackets': (repeated(b'"[",['), True),
    'unicode escapes': (repeated(b'\\u00e9', b'"', b'"'), False),
    'long unicode escapes': (repeated(b'\\uD83D\\uDE00', b'["', b'"]'), False),
    'numbers': (repeated(b'1,', b'[', b'1]'), False),
}


@pytest.mark.parametrize(('payload', 'deeper'), ADVERSARIAL.values(), ids=list(ADVERSARIAL.keys()))
def test_a_body_up_to_the_limit_is_checked_in_linear_time(payload: bytes, deeper: bool) -> None:
    assert 0.99 * LIMIT < len(payload) <= LIMIT
    took = []
    for _ in range(3):  # the shortest of three: the check's own time (CPU, this thread's)
        started = time.thread_time()
        answer = deeper_than(payload, JSON_MAX_DEPTH)
        took.append(time.thread_time() - started)

    assert answer == deeper
    assert min(took) < CHECK_MAX_SEC, f'{min(took) * 1000:.1f} ms'


@pytest.mark.parametrize(
    ('payload', 'code', 'message'),
    [
        (b'[' * 33 + b']' * 33, 'nesting_too_deep', 'the request nests deeper than 32 levels'),
        (b'{"a": 1, "a": 2}', 'invalid_request', "the key 'a' is given twice"),
        (b'[NaN]', 'invalid_request', 'NaN is not a JSON number'),
        (b'[1e400]', 'invalid_request', '1e400 is too large for a number here'),
        (b'{"a": "\xff"}', 'invalid_request', 'not UTF-8 text: byte 0xff at offset 7'),
        (b'{"a": ', 'invalid_request', 'not valid JSON: Expecting value (line 1, column 7)'),
        (b'[' + b'1,' * 50 + b'1]', 'payload_too_large', 'the request is 103 bytes; at most 100'),
    ],
)
def test_load_refuses_what_is_not_plain_json_of_the_bounds(
    payload: bytes, code: str, message: str
) -> None:
    with pytest.raises(RefusedJsonError) as refused:
        load(payload, max_bytes=100)

    assert (refused.value.code, refused.value.message[: len(message)]) == (code, message)


def test_load_reads_plain_json_nested_up_to_the_bound() -> None:
    text = b'{"a": ' * 31 + b'["\\"[{"]' + b'}' * 31

    assert depth_of(load(text)) == JSON_MAX_DEPTH
