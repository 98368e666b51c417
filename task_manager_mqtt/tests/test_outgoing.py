"""What the bridge sends fits the broker's message size limit (no broker, no ROS)."""

import json
from typing import Any

from task_manager.testing.gateway import check
from task_manager_mqtt.outgoing import fitted

MAX_BYTES = 2000


def task(task_id: str, result: dict[str, Any] | None = None) -> dict[str, Any]:
    return {'task_id': task_id, 'task_name': 'fib', 'source': 'CLOUD', 'status': 'DONE',
            'result': result, 'feedback': None, 'sequence': 1}  # fmt: skip


def test_a_document_that_fits_is_sent_as_it_is() -> None:
    document = task('t1', {'sequence': [1, 2, 3]})
    assert json.loads(fitted('result', document, MAX_BYTES)) == document


def test_a_history_too_large_is_an_error_reply_saying_how_to_ask_for_less() -> None:
    history = {'request_id': 'h1', 'ok': True, 'op': 'history',
               'tasks': [task(f't{n}') for n in range(50)]}  # fmt: skip
    reply = check(json.loads(fitted('reply', history, MAX_BYTES)), 'mqtt_reply')
    assert (reply['request_id'], reply['ok'], reply['error']['code']) == (
        'h1', False, 'reply_too_large',
    )  # fmt: skip
    assert 'ask for fewer (limit)' in reply['error']['message']


def test_a_result_too_large_goes_out_without_it() -> None:
    big = task('t1', {'sequence': list(range(1000))})
    sent = check(json.loads(fitted('result', big, MAX_BYTES)), 'task')
    assert sent['task_id'] == 't1' and sent['result'] == {'omitted_bytes': 3904}
    event = {'event': 'ENDED', 'stamp': '2025-01-01T00:00:00Z', 'task': big}
    assert json.loads(fitted('event', event, MAX_BYTES))['task']['result'] == sent['result']
    started = {'request_id': 'r1', 'ok': True, 'op': 'start_task', 'task_id': 't1', 'task': big}
    assert json.loads(fitted('reply', started, MAX_BYTES))['task']['result'] == sent['result']
