"""Bad requests get one reply naming what is wrong, before anything reaches a Task Manager;
those without a usable request_id are dead letters (no ROS, no broker)."""

import json
from typing import Any, cast

import pytest

from task_manager.protocol.strict_json import MAX_DEPTH
from task_manager.testing.gateway import check
from task_manager_mqtt.requests import Answer, RequestHandler

MAX_BYTES = 2000


def answer_to(payload: bytes, retained: bool = False) -> Answer:
    # no client: none of these requests may get as far as the Task Manager
    handler = RequestHandler(client=None, source='CLOUD', max_payload_bytes=MAX_BYTES)  # type: ignore[arg-type]
    return handler.answer(payload, retained)


def reply_to(payload: bytes, retained: bool = False) -> dict[str, Any]:
    answer = answer_to(payload, retained)
    assert answer.dead_letter is None
    return cast(dict[str, Any], check(answer.reply, 'mqtt_reply'))


@pytest.mark.parametrize(
    ('payload', 'code', 'field', 'words'),
    [
        (b'{"request_id": "r1", "op": ', 'invalid_request', '', 'not valid JSON'),
        (b'{"request_id": "r1", "op": "stop", "x": "\xff"}', 'invalid_request', '', 'not UTF-8'),
        (b'{"request_id": "r1"}', 'invalid_request', '', 'missing field "op"'),
        (b'{"request_id": "r1", "op": "dance"}', 'invalid_request', 'op', 'allowed: start_task'),
        (b'{"request_id": "r1", "op": "start_task"}', 'invalid_request', 'task_name', 'required'),
        (
            b'{"request_id": "r1", "op": "start_task", "task_name": "x", "task_dat": {}}',
            'invalid_request',
            'task_dat',
            'unknown field',
        ),
        (
            b'{"request_id": "r1", "op": "cancel", "task_ids": []}',
            'invalid_request',
            'task_ids',
            '',
        ),
        (
            json.dumps({'request_id': 'r1', 'op': 'stop', 'x': 'y' * MAX_BYTES}).encode(),
            'payload_too_large',
            '',
            f'at most {MAX_BYTES}',
        ),
        (
            b'{"request_id": "r1", "op": "stop", "x": ' + b'[' * 500 + b']' * 500 + b'}',
            'nesting_too_deep',
            '',
            f'at most {MAX_DEPTH} allowed',
        ),
        (b'{"request_id": "r1", "op": "stop"}', 'retained_request', '', 'without the retain flag'),
    ],
)
def test_bad_requests_get_an_error_reply(payload: bytes, code: str, field: str, words: str) -> None:
    reply = reply_to(payload, retained=code == 'retained_request')
    assert reply['request_id'] == 'r1' and reply['ok'] is False
    assert reply['ok'] is False and reply['error']['code'] == code
    assert reply['error']['field'] == field and words in reply['error']['message']


def test_the_reply_to_a_bad_request_carries_its_request_id() -> None:
    reply = reply_to(b'{"request_id": "r9", "op": "start_task"}')
    assert (reply['request_id'], reply['op']) == ('r9', 'start_task')


@pytest.mark.parametrize(
    ('payload', 'words'),
    [
        (b'', 'not valid JSON'),
        (b'hello', 'not valid JSON'),
        (b'\xff\xfe{}', 'not UTF-8'),
        (b'[1, 2]', 'JSON object'),
        (b'[' * 500 + b']' * 500, f'at most {MAX_DEPTH} allowed'),
        (b'{"op": "stop"}', 'request_id: required'),
        (b'{"request_id": 42, "op": "stop"}', 'a string of 1 to 256 characters, got int'),
        (b'{"request_id": "", "op": "stop"}', 'got 0 characters'),
        (b'{"request_id": "%s", "op": "stop"}' % (b'r' * 257), 'got 257 characters'),
        (b'{"op": "stop", "pad": "%s"}' % (b'y' * MAX_BYTES), f'at most {MAX_BYTES} allowed'),
    ],
)
def test_what_cannot_be_addressed_is_a_dead_letter(payload: bytes, words: str) -> None:
    answer = answer_to(payload)
    assert answer.reply is None and answer.dead_letter is not None
    assert words in answer.dead_letter['message'], answer.dead_letter
