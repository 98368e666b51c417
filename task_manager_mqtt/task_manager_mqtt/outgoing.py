"""What the bridge sends fits in one message: at most `--max-payload-bytes`, or the broker's
Maximum Packet Size if smaller. A larger message would make the broker drop the bridge's
connection, and the MQTT client would send it again at every reconnection.

A document over the limit is made smaller, step by step, until it fits:

1. In each Task document, a `result` or `feedback` is replaced by `{"omitted_bytes": N}` and
   an `error_message` cut to REASON_MAX_CHARACTERS. A reply with a history (`tasks`) is
   instead a `reply_too_large` error saying how many tasks would fit.
2. A list of tasks (`active_tasks`, the declared `tasks`) keeps as many as fit, running ones
   first, and says how many it left out (`omitted`).
3. A Task document's `decisions` become one `omitted` entry counting them.
4. A Task document keeps only its names, status and sequence.

What still does not fit (a limit of a few hundred bytes) is a `reply_too_large` error for a
reply, and for anything else not sent (None), logged.
"""

import logging
import time
from collections.abc import Callable
from typing import Any

from task_manager.core.bounds import REASON_MAX_CHARACTERS, cut_text
from task_manager.core.text.json_text import compact_json
from task_manager.protocol.errors import RefusalCode
from task_manager_mqtt.topics import TopicName

LOG = logging.getLogger('task_manager_mqtt')
BULKY = ('result', 'feedback')
"""The fields of a Task document that may be of any size."""
ESSENTIAL = ('task_id', 'task_name', 'source', 'status', 'error_code', 'mission_id', 'sequence')
"""What a Task document keeps at the last step."""
LISTS = (TopicName.ACTIVE_TASKS, TopicName.TASKS)
"""The topics whose documents hold a list of tasks, `tasks`, that may be cut."""
RUNNING_FIRST = {'IN_PROGRESS': 0, 'PAUSED': 0}
"""The rank of a task when a list is cut (the others: 1)."""
LOG_PERIOD_SEC = 60.0
"""The most often one topic's documents are logged as made smaller."""

Document = dict[str, Any]


class Outgoing:
    """Makes documents fit (see the module); logs at most once a minute per topic."""

    def __init__(self) -> None:
        # key: topic name, value: when a document of it was last logged as made smaller
        self._logged: dict[str, float] = {}

    def fitted(
        self, topic_name: str, document: Document, max_bytes: int, encoded: bytes | None = None
    ) -> bytes | None:
        """The payload of `document` for the topic `topic_name` (reply, result, ...) in at
        most `max_bytes`; None when nothing that fits can be made of it. `encoded`: the
        document's JSON text, when the caller has it already (active_list.py)."""
        payload = _encoded(document) if encoded is None else encoded
        if len(payload) <= max_bytes:
            return payload
        if topic_name == TopicName.REPLY and isinstance(document.get('tasks'), list):
            self._log(topic_name, len(payload), max_bytes, 'refused: reply_too_large')
            return _too_large(document, len(payload), max_bytes)
        for step, made in enumerate(_smaller(topic_name, document, max_bytes), 1):
            fitting = _encoded(made)
            if len(fitting) <= max_bytes:
                self._log(topic_name, len(payload), max_bytes, f'made smaller (step {step})')
                return fitting
        self._log(topic_name, len(payload), max_bytes, 'nothing that fits: not sent')
        if topic_name == TopicName.REPLY:
            return _too_large(document, len(payload), max_bytes)
        return None

    def _log(self, topic_name: str, size: int, max_bytes: int, outcome: str) -> None:
        now = time.monotonic()
        if now - self._logged.get(topic_name, -LOG_PERIOD_SEC) < LOG_PERIOD_SEC:
            return
        self._logged[topic_name] = now
        LOG.warning(
            '%s of %d bytes, over the %d a message may hold: %s (logged once a minute per topic)',
            topic_name,
            size,
            max_bytes,
            outcome,
        )


def fitted(topic_name: str, document: Document, max_bytes: int) -> bytes | None:
    """Outgoing().fitted, for one document."""
    return Outgoing().fitted(topic_name, document, max_bytes)


def _encoded(document: Document) -> bytes:
    return compact_json(document).encode()


def _smaller(topic_name: str, document: Document, max_bytes: int) -> list[Document]:
    """`document` made smaller by the module's steps 1 to 4, each from the one before."""
    bulk = _each_task(document, _task_without_bulk)
    if topic_name in LISTS and isinstance(bulk.get('tasks'), list):
        return [bulk, _as_many_as_fit(bulk, max_bytes)]
    few_decisions = _each_task(bulk, _task_with_decisions_counted)
    return [bulk, few_decisions, _each_task(few_decisions, _essential_task)]


def _each_task(document: Document, change: Callable[[Document], Document]) -> Document:
    """`document` with `change` applied to each Task document in it (or to it, if one)."""
    if 'task_id' in document and 'status' in document:  # a Task document itself
        return change(document)
    shrunk = dict(document)
    if isinstance(shrunk.get('task'), dict):
        shrunk['task'] = change(shrunk['task'])
    if isinstance(shrunk.get('tasks'), list):
        shrunk['tasks'] = [change(t) if isinstance(t, dict) else t for t in shrunk['tasks']]
    return shrunk


def _task_without_bulk(task: Document) -> Document:
    shrunk = {
        key: {'omitted_bytes': len(_encoded(value))}
        if key in BULKY and isinstance(value, dict)
        else value
        for key, value in task.items()
    }
    if isinstance(task.get('error_message'), str):
        shrunk['error_message'] = cut_text(task['error_message'], REASON_MAX_CHARACTERS)
    return shrunk


def _task_with_decisions_counted(task: Document) -> Document:
    decisions = task.get('decisions')
    if not isinstance(decisions, list) or not decisions:
        return task
    count = sum(d.get('omitted', 0) or 1 for d in decisions if isinstance(d, dict))
    newest = decisions[-1] if isinstance(decisions[-1], dict) else {}
    entry = {
        'at': newest.get('at'),
        'decision': 'omitted',
        'reason': f'{count} decisions left out so that this message fits',
        'omitted': count,
    }
    return {**task, 'decisions': [entry]}


def _essential_task(task: Document) -> Document:
    return {key: task[key] for key in ESSENTIAL if key in task}


def _as_many_as_fit(document: Document, max_bytes: int) -> Document:
    """`document` whose `tasks` keeps the first that fit, running ones first, and says how
    many it left out (`omitted`)."""
    tasks = [t for t in document['tasks'] if isinstance(t, dict)]
    tasks.sort(key=lambda task: RUNNING_FIRST.get(task.get('status', ''), 1))
    # the document without its tasks, `omitted` as large as it can be
    room = max_bytes - len(_encoded({**document, 'tasks': [], 'omitted': len(tasks)}))
    kept = 0
    for task in tasks:
        room -= len(_encoded(task)) + (1 if kept else 0)  # the comma between two
        if room < 0:
            break
        kept += 1
    return {**document, 'tasks': tasks[:kept], 'omitted': len(tasks) - kept}


def _too_large(reply: Document, size: int, max_bytes: int) -> bytes:
    tasks = reply.get('tasks')
    if isinstance(tasks, list):
        fit = _tasks_that_fit(reply, tasks, max_bytes)
        message = (
            f'the reply ({len(tasks)} tasks) would be {size} bytes; at most {max_bytes} fit in '
            f'a message: ask for fewer (limit; the first {fit} of these fit), and page with '
            'after_sequence'
        )
        field = 'limit'
    else:
        message = (
            f'the reply would be {size} bytes; at most {max_bytes} fit in a message: ask for less'
        )
        field = ''
    error = {'code': RefusalCode.REPLY_TOO_LARGE, 'message': message, 'field': field}
    fields = ('request_id', 'op')
    return compact_json({**{k: reply[k] for k in fields if k in reply}, 'ok': False,
                         'error': error}).encode()  # fmt: skip


def _tasks_that_fit(reply: Document, tasks: list[Any], max_bytes: int) -> int:
    """How many of the first `tasks` the reply may hold in `max_bytes`."""
    room = max_bytes - len(_encoded({**reply, 'tasks': []}))
    for count, task in enumerate(tasks):
        room -= len(_encoded(task)) + (1 if count else 0)  # the comma between two
        if room < 0:
            return count
    return len(tasks)
