"""Bad requests get one reply naming what is wrong, before anything reaches a Task Manager."""

import json
from typing import Any

import pytest

from task_manager.testing.gateway import check
from task_manager_mqtt.requests import RequestHandler

MAX_BYTES = 2000


def reply_to(payload: bytes) -> dict[str, Any]:
    # no client: none of these requests may get as far as the Task Manager
    handler = RequestHandler(client=None, source='CLOUD', max_payload_bytes=MAX_BYTES)  # type: ignore[arg-type]
    return check(handler.reply(payload), 'mqtt_reply')


@pytest.mark.parametrize(
    ('payload', 'code', 'field', 'words'),
    [
        (b'{"request_id": "r1", "op": ', 'invalid_request', '', 'not valid JSON'),
        (b'[1, 2]', 'invalid_request', '', 'JSON object'),
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
        (b'{"op": "stop"}', 'invalid_request', 'request_id', 'required'),
        (
            json.dumps({'request_id': 'r1', 'op': 'stop', 'x': 'y' * MAX_BYTES}).encode(),
            'payload_too_large',
            '',
            f'at most {MAX_BYTES}',
        ),
    ],
)
def test_bad_requests_get_an_error_reply(payload: bytes, code: str, field: str, words: str) -> None:
    reply = reply_to(payload)
    assert reply['ok'] is False and reply['error']['code'] == code
    assert reply['error']['field'] == field and words in reply['error']['message']


def test_the_reply_to_a_bad_request_carries_its_request_id() -> None:
    reply = reply_to(b'{"request_id": "r9", "op": "start_task"}')
    assert (reply['request_id'], reply['op']) == ('r9', 'start_task')
