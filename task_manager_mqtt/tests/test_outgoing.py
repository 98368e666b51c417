"""What the bridge sends fits the broker's message size limit (no broker, no ROS)."""

import json
import logging
from typing import Any

import pytest

from task_manager.testing.gateway import check
from task_manager_mqtt.outbox import ResultOutbox
from task_manager_mqtt.outgoing import Outgoing, fitted

MAX_BYTES = 2000
LONG_ID = 'x' * 250
STAMP = '2025-01-01T00:00:00Z'


def task(
    task_id: str, result: dict[str, Any] | None = None, status: str = 'DONE', **more: Any
) -> dict[str, Any]:
    return {'task_id': task_id, 'task_name': 'fib', 'source': 'CLOUD', 'status': status,
            'result': result, 'feedback': None, 'sequence': 1, **more}  # fmt: skip


def decisions(count: int) -> list[dict[str, Any]]:
    return [{'at': STAMP, 'decision': 'reprioritized', 'reason': f'priority {n} -> {n + 1}'}
            for n in range(count)]  # fmt: skip


def sent(topic_name: str, document: dict[str, Any], max_bytes: int = MAX_BYTES) -> Any:
    payload = fitted(topic_name, document, max_bytes)
    assert payload is not None and len(payload) <= max_bytes
    return json.loads(payload)


def test_a_document_that_fits_is_sent_as_it_is() -> None:
    document = task('t1', {'sequence': [1, 2, 3]})
    assert json.loads(fitted('result', document, MAX_BYTES) or b'') == document


def test_a_history_too_large_is_an_error_reply_saying_how_many_tasks_fit() -> None:
    tasks = [task(f't{n}') for n in range(50)]
    history = {'request_id': 'h1', 'ok': True, 'op': 'history', 'tasks': tasks}
    reply = check(sent('reply', history), 'mqtt_reply')
    assert (reply['request_id'], reply['ok'], reply['error']['code']) == (
        'h1', False, 'reply_too_large',
    )  # fmt: skip
    assert reply['error']['field'] == 'limit'
    fit = int(reply['error']['message'].split('ask for fewer (limit; the first ')[1].split()[0])
    assert 'and page with after_sequence' in reply['error']['message']
    assert sent('reply', {**history, 'tasks': tasks[:fit]})['ok']
    assert not sent('reply', {**history, 'tasks': tasks[: fit + 1]})['ok']


def test_a_result_too_large_goes_out_without_it() -> None:
    big = task('t1', {'sequence': list(range(1000))})
    result = check(sent('result', big), 'task')
    assert result['task_id'] == 't1' and result['result'] == {'omitted_bytes': 3904}
    event = {'event': 'ENDED', 'stamp': STAMP, 'task': big}
    assert sent('event', event)['task']['result'] == result['result']
    started = {'request_id': 'r1', 'ok': True, 'op': 'start_task', 'task_id': 't1', 'task': big}
    assert sent('reply', started)['task']['result'] == result['result']


def test_1500_active_tasks_with_long_ids_keep_as_many_as_fit_running_first() -> None:
    queued = [task(f'{LONG_ID}-q{n}', status='QUEUED', decisions=decisions(2))
              for n in range(1400)]  # fmt: skip
    running = [task(f'{LONG_ID}-r{n}', status='IN_PROGRESS', feedback={'percent': n})
               for n in range(100)]  # fmt: skip
    document = {'timestamp': STAMP, 'tasks': queued + running}
    assert len(json.dumps(document)) > 800_000

    active = check(sent('active_tasks', document, 65_536), 'mqtt_active_tasks')

    kept = [t['task_id'] for t in active['tasks']]
    assert kept[:100] == [t['task_id'] for t in running]  # the running ones first
    assert kept[100:] == [t['task_id'] for t in queued[: len(kept) - 100]]
    assert active['omitted'] == 1500 - len(kept) > 0
    assert len(kept) > 100
    assert active['tasks'][0]['feedback'] == {'omitted_bytes': 13}


def test_a_limit_too_small_for_any_task_leaves_them_all_out() -> None:
    document = {'timestamp': STAMP, 'tasks': [task(LONG_ID, status='IN_PROGRESS')]}

    active = check(sent('active_tasks', document, 200), 'mqtt_active_tasks')

    assert (active['tasks'], active['omitted']) == ([], 1)


def test_declared_tasks_over_the_limit_keep_as_many_as_fit() -> None:
    declared = [{'task_name': f'task_{n}', 'msg_interface': 'std_srvs/srv/Trigger',
                 'goal_schema': {'description': 'x' * 500}} for n in range(10)]  # fmt: skip

    document = sent('tasks', {'timestamp': STAMP, 'tasks': declared})

    assert [t['task_name'] for t in document['tasks']] == ['task_0', 'task_1', 'task_2']
    assert document['omitted'] == 7


def test_a_task_with_many_decisions_and_a_long_error_is_made_smaller_step_by_step() -> None:
    error = 'e' * 5000
    left_out = {'at': STAMP, 'decision': 'omitted', 'reason': 'r', 'omitted': 900}
    many = task(LONG_ID, {'error': error}, status='ERROR', error_message=error,
                decisions=[*decisions(99), left_out])  # fmt: skip

    result = check(sent('result', many, 4000), 'task')
    bare = check(sent('result', many, 900), 'task')

    assert result['error_message'].endswith('(4000 more characters)')
    assert result['decisions'] == [{'at': STAMP, 'decision': 'omitted', 'omitted': 999,
                                    'reason': '999 decisions left out so that this message '
                                    'fits'}]  # fmt: skip
    assert bare == {'task_id': LONG_ID, 'task_name': 'fib', 'source': 'CLOUD',
                    'status': 'ERROR', 'sequence': 1}  # fmt: skip


def test_what_nothing_can_make_fit_is_not_sent_and_a_reply_is_an_error() -> None:
    assert fitted('result', task(LONG_ID), 100) is None
    reply = {'request_id': 'w1', 'ok': True, 'op': 'why', 'decisions': decisions(100)}
    refused = sent('reply', reply, 400)
    assert refused['error']['code'] == 'reply_too_large' and refused['error']['field'] == ''


def test_a_topic_made_smaller_again_and_again_is_logged_once_a_minute(
    caplog: pytest.LogCaptureFixture,
) -> None:
    outgoing = Outgoing()
    document = {'timestamp': STAMP, 'tasks': [task(f'{LONG_ID}{n}') for n in range(100)]}
    with caplog.at_level(logging.WARNING, logger='task_manager_mqtt'):
        for _ in range(50):
            assert outgoing.fitted('active_tasks', document, MAX_BYTES) is not None
        outgoing.fitted('result', task(LONG_ID, {'x': 'y' * 5000}), MAX_BYTES)

    lines = [record.getMessage() for record in caplog.records]
    assert len(lines) == 2
    assert lines[0].startswith('active_tasks of ') and 'made smaller' in lines[0]


def test_a_result_that_cannot_be_sent_counts_as_acknowledged(tmp_path: Any) -> None:
    outbox = ResultOutbox(tmp_path / 'acked')
    outbox.start_at(4)
    outbox.before_send()
    outbox.mark_sent(5, message_id=1, task_id='five')
    outbox.before_send()
    outbox.skip(6, task_id='six')

    assert (outbox.sent, outbox.acked) == (6, 4)  # 5 waits for its acknowledgement
    outbox.on_ack(1)
    assert (outbox.acked, outbox.acked_task_id) == (6, 'six')
    assert (tmp_path / 'acked').read_text() == '6\nsix\n'
