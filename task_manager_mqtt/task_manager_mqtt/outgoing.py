"""What the bridge sends fits in one message: at most `--max-payload-bytes`, the broker's
`message_size_limit` too (a broker drops a message over its limit, and the result with it).

A reply with a history over the limit becomes a `reply_too_large` error saying how to ask for
less; in any other document, a task's `result` or `feedback` that makes it too large is
replaced by `{"omitted_bytes": N}`.
"""

import logging
from typing import Any

from task_manager.core.json_text import compact_json

LOG = logging.getLogger('task_manager_mqtt')
BULKY = ('result', 'feedback')
"""The fields of a Task document that may be of any size."""


def fitted(topic_name: str, document: dict[str, Any], max_bytes: int) -> bytes:
    """The payload of `document` for the topic `topic_name` (reply, result, ...), made to fit
    in `max_bytes` as the module says; over it still only if nothing could be cut."""
    payload = compact_json(document).encode()
    if len(payload) <= max_bytes:
        return payload
    if topic_name == 'reply' and document.get('tasks'):
        return _too_large(document, len(payload), max_bytes)
    LOG.warning(
        '%s of %d bytes, over %d: the results and feedback it holds are omitted',
        topic_name,
        len(payload),
        max_bytes,
    )
    payload = compact_json(_without_bulk(document)).encode()
    if len(payload) > max_bytes and topic_name == 'reply':
        return _too_large(document, len(payload), max_bytes)
    return payload


def _too_large(reply: dict[str, Any], size: int, max_bytes: int) -> bytes:
    count = len(reply.get('tasks') or ())
    message = (
        f'the reply ({count} tasks) would be {size} bytes; at most {max_bytes} fit in a message: '
        'ask for fewer (limit), and page with after_sequence'
    )
    error = {'code': 'reply_too_large', 'message': message, 'field': ''}
    fields = ('request_id', 'op')
    return compact_json({**{k: reply[k] for k in fields if k in reply}, 'ok': False,
                         'error': error}).encode()  # fmt: skip


def _without_bulk(document: dict[str, Any]) -> dict[str, Any]:
    """`document` with the result and feedback of each Task document in it omitted."""
    if 'task_id' in document and 'status' in document:  # a Task document itself
        return _task_without_bulk(document)
    shrunk = dict(document)
    if isinstance(shrunk.get('task'), dict):
        shrunk['task'] = _task_without_bulk(shrunk['task'])
    if isinstance(shrunk.get('tasks'), list):
        shrunk['tasks'] = [_task_without_bulk(t) if isinstance(t, dict) else t
                           for t in shrunk['tasks']]  # fmt: skip
    return shrunk


def _task_without_bulk(task: dict[str, Any]) -> dict[str, Any]:
    return {
        key: {'omitted_bytes': len(compact_json(value).encode())}
        if key in BULKY and isinstance(value, dict)
        else value
        for key, value in task.items()
    }
