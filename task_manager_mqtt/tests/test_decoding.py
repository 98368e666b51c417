"""Fuzzing the request decoder: any bytes, any JSON, any depth and size get exactly one reply
or one dead letter, and nothing raises (no broker, no ROS: nothing can start here)."""

import json
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from task_manager.protocol import models, mqtt
from task_manager_mqtt.decoding import (
    MAX_DEPTH,
    OPS,
    decode,
    deeper_than,
    load_json,
    top_level_request_id,
)
from task_manager_mqtt.requests import RequestHandler

MAX_BYTES = 4096
EXAMPLES = 200

scalars = st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20)
json_values = st.recursive(
    scalars,
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=10), inner),
    max_leaves=30,
)
request_like = st.fixed_dictionaries(
    {},
    optional={
        'request_id': scalars | st.text(min_size=1, max_size=300),
        'op': st.sampled_from([*OPS, 'dance']) | scalars,
        'task_name': scalars,
        'task_data': json_values,
        'task_ids': json_values,
        'subtasks': json_values,
        'limit': json_values,
    },
)


@st.composite
def nested(draw: st.DrawFn) -> bytes:
    """A request (or not) holding brackets nested up to 3,000 deep, balanced or not."""
    depth = draw(st.integers(0, 3000))
    opening = draw(st.sampled_from([b'[', b'{"a": ']))
    closing = b']' if opening == b'[' else b'}'
    inner = opening * depth + b'1' + closing * draw(st.integers(0, depth))
    if draw(st.booleans()):
        return inner
    request_id = draw(st.sampled_from([b'"r1"', b'42', b'""']))
    return b'{"request_id": %s, "op": "start_task", "task_data": %s}' % (request_id, inner)


payloads = st.one_of(
    st.binary(max_size=2 * MAX_BYTES),
    json_values.map(lambda value: json.dumps(value).encode()),
    request_like.map(lambda value: json.dumps(value).encode()),
    nested(),
    st.tuples(request_like, st.integers(0, 2 * MAX_BYTES)).map(
        lambda pair: json.dumps({**pair[0], 'pad': 'x' * pair[1]}).encode()
    ),
)


def outcome(payload: bytes, retained: bool, max_bytes: int = MAX_BYTES) -> tuple[str, Any]:
    """('run', request) for a valid request; else ('reply', Reply) or ('dead', reason)."""
    # no client: a message that got as far as the Task Manager would fail (internal_error)
    handler = RequestHandler(client=None, source='CLOUD', max_payload_bytes=max_bytes)  # type: ignore[arg-type]
    decoded = decode(payload, max_bytes, retained)
    assert (decoded.request is None) != (decoded.error is None), decoded
    if decoded.request is not None:  # only a valid, addressed, not retained request runs
        assert decoded.addressed and not retained and len(payload) <= max_bytes
        return 'run', decoded.request
    answer = handler.answer(payload, retained)
    assert (answer.reply is None) != (answer.dead_letter is None), answer
    if answer.reply is not None:
        reply = mqtt.Reply.model_validate(answer.reply)
        assert not reply.ok and reply.request_id == decoded.request_id != ''
        assert reply.error is not None and reply.error.code != 'internal_error', reply
        return 'reply', reply
    assert not decoded.addressed
    detail = models.ErrorDetail.model_validate(answer.dead_letter)
    assert detail.code != 'internal_error' and detail.message, detail
    return 'dead', detail


@settings(max_examples=EXAMPLES, deadline=None)
@given(payload=payloads, retained=st.booleans())
def test_any_message_gets_one_reply_or_one_dead_letter(payload: bytes, retained: bool) -> None:
    outcome(payload, retained)


@settings(max_examples=EXAMPLES // 2, deadline=None)
@given(value=json_values)
def test_the_depth_check_agrees_with_the_parsed_document(value: Any) -> None:
    text = json.dumps(value).encode()
    assert deeper_than(text, MAX_DEPTH) == (depth_of(value) > MAX_DEPTH)
    assert json.dumps(load_json(text)) == text.decode()  # (NaN is not equal to itself)


@settings(max_examples=EXAMPLES // 2, deadline=None)
@given(document=request_like, junk=st.binary(max_size=50))
def test_the_scan_finds_the_request_id_the_parser_finds(
    document: dict[str, Any], junk: bytes
) -> None:
    text = json.dumps(document).encode()
    request_id = document.get('request_id')
    usable = isinstance(request_id, str) and 0 < len(request_id) <= models.NAME_MAX
    expected = request_id if usable else ''
    assert top_level_request_id(text) == expected
    if 'request_id' in document:  # the rest broken (too large, too deep, cut): still found
        start = json.dumps({'request_id': request_id}).encode()[:-1]
        assert top_level_request_id(start + b', ' + junk) == expected


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


def test_a_request_nested_5000_deep_is_refused_by_its_id() -> None:
    deep = b'[' * 5000 + b']' * 5000  # 10 KB: the issue's
    payload = b'{"request_id": "deep", "op": "start_task", "task_data": %s}' % deep
    kind, reply = outcome(payload, retained=False, max_bytes=1 << 20)
    assert kind == 'reply' and reply.error.code == 'nesting_too_deep'
    assert f'at most {MAX_DEPTH}' in reply.error.message
