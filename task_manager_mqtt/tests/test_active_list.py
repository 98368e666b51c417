"""The bridge's active list: its document's text made from each task's kept text is the text of
the whole document (no broker, no ROS)."""

import json
import math
from typing import Any

from hypothesis import given
from hypothesis import strategies as st

from task_manager.core.text.json_text import compact_json
from task_manager_mqtt.active_list import ActiveList
from task_manager_mqtt.outgoing import Outgoing

STAMP = '2026-11-29T21:00:00.123456+00:00'

values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(), inner, max_size=3),
    max_leaves=8,
)
tasks = st.builds(
    lambda task_id, status, result: {'task_id': task_id, 'status': status, 'result': result},
    st.text(min_size=1, max_size=8),
    st.sampled_from(['RECEIVED', 'IN_PROGRESS', 'PAUSED']),
    values,
)
changes = st.lists(st.tuples(st.booleans(), tasks), max_size=12)


def task(task_id: str, status: str = 'IN_PROGRESS', **more: Any) -> dict[str, Any]:
    return {'task_id': task_id, 'task_name': 'fib', 'status': status, **more}


@given(changes)
def test_the_payload_is_the_whole_documents_text_after_any_changes(
    steps: list[tuple[bool, dict[str, Any]]],
) -> None:
    active = ActiveList()
    for ended, each in steps:
        if ended:
            active.discard(each['task_id'])
        else:
            active.put(each['task_id'], each)

    assert active.payload(STAMP) == compact_json(active.document(STAMP)).encode()


@given(st.lists(tasks, max_size=8))
def test_replace_keeps_the_tasks_in_their_order(listed: list[dict[str, Any]]) -> None:
    active = ActiveList()
    active.put('gone', task('gone'))

    active.replace(listed)

    by_id = {each['task_id']: each for each in listed}
    assert active.document(STAMP)['tasks'] == list(by_id.values())
    assert active.payload(STAMP) == compact_json(active.document(STAMP)).encode()


def test_a_changed_task_keeps_its_place_and_shows_its_change() -> None:
    active = ActiveList()
    for task_id in ('a', 'b', 'c'):
        active.put(task_id, task(task_id, 'RECEIVED'))

    active.put('b', task('b', 'IN_PROGRESS', feedback={'left': math.nan}))
    active.discard('a')
    active.discard('never there')

    sent = json.loads(active.payload(STAMP))
    assert sent == {
        'timestamp': STAMP,
        'tasks': [task('b', 'IN_PROGRESS', feedback={'left': None}), task('c', 'RECEIVED')],
    }
    assert len(active) == 2


def test_an_empty_list() -> None:
    assert json.loads(ActiveList().payload(STAMP)) == {'timestamp': STAMP, 'tasks': []}


def test_a_list_over_the_limit_is_cut_as_one_encoded_there() -> None:
    active = ActiveList()
    for n in range(40):
        active.put(f't{n}', task(f't{n}', result={'sequence': list(range(30))}))
    document, payload = active.document(STAMP), active.payload(STAMP)

    fitted = Outgoing().fitted('active_tasks', document, 1500, payload)

    assert len(payload) > 1500
    assert fitted is not None and fitted == Outgoing().fitted('active_tasks', document, 1500)
    assert len(fitted) <= 1500 and json.loads(fitted)['omitted'] > 0
