"""TaskHistory: the SQLite store of every request, on real files in a temporary folder."""

import json
import os
import sqlite3
from pathlib import Path

import pytest

from task_manager.core.bounds import HISTORY_RESULT_MAX_BYTES, HISTORY_TASK_DATA_MAX_BYTES
from task_manager.core.history.rows import ROW_OVERHEAD_BYTES
from task_manager.core.history.store import (
    SCHEMA_VERSION,
    HistoryError,
    HistoryInUseError,
    HistoryQuery,
    TaskHistory,
)
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.core.task import TaskRecord
from task_manager.core.task_spec import InterfaceName, TaskKind, TaskSpec

FIB = TaskSpec('fib', '/fib', InterfaceName('test_msgs', TaskKind.ACTION, 'Fibonacci'))
NAV = TaskSpec('nav', '/nav', InterfaceName('test_msgs', TaskKind.ACTION, 'Fibonacci'))

# The first schema, exactly as version 1 wrote it: every later version must open it.
SCHEMA_V1_FILE = """
CREATE TABLE tasks (
    entry INTEGER PRIMARY KEY, task_id TEXT NOT NULL, task_name TEXT NOT NULL,
    source TEXT NOT NULL, mission_id TEXT NOT NULL, task_data TEXT NOT NULL,
    status TEXT NOT NULL, error_code TEXT NOT NULL, result TEXT, received REAL NOT NULL,
    started REAL, ended REAL, sequence INTEGER UNIQUE);
CREATE INDEX tasks_unfinished ON tasks (entry) WHERE sequence IS NULL;
CREATE INDEX tasks_by_name ON tasks (task_name, sequence);
CREATE INDEX tasks_by_end ON tasks (ended);
INSERT INTO tasks VALUES (1, 'old', 'fib', 'CLI', '', '{}', 'DONE', '', '{}', 1.0, 2.0, 3.0, 1);
PRAGMA user_version = 1;
"""


def ended(task_id: str, spec: TaskSpec = FIB, at: float = 100.0, **result: object) -> TaskRecord:
    record = TaskRecord(task_id, spec, 'CLI', task_data='{"order": 1}', received_at=at - 2)
    record.mark_started(now=at - 1)
    record.mark_ended(TaskStatus.DONE, dict(result), now=at)
    return record


def test_an_ended_task_is_stored_with_its_data_stamps_result_and_a_sequence(
    tmp_path: Path,
) -> None:
    history = TaskHistory(str(tmp_path / 'h.sqlite'))
    record = TaskRecord('t1', FIB, 'CLOUD', task_data='{"order": 1}', received_at=10.0)

    assert history.write(record) is None  # received: no sequence yet
    record.mark_started(now=11.0)
    history.write(record)
    record.mark_ended(TaskStatus.DONE, {'sequence': [1], 'nan': float('nan')}, now=12.5)
    sequence = history.write(record)
    history.flush()
    history.close()

    rows = TaskHistory(str(tmp_path / 'h.sqlite')).query(HistoryQuery())
    assert sequence == 1
    assert [(r.task_id, r.source, r.task_data, r.status, r.sequence) for r in rows] == [
        ('t1', 'CLOUD', '{"order": 1}', 'DONE', 1)
    ]
    assert (rows[0].received, rows[0].started, rows[0].ended) == (10.0, 11.0, 12.5)
    assert json.loads(rows[0].result or '') == {'sequence': [1], 'nan': None}


def test_changes_wait_for_the_flush_and_one_flush_is_one_transaction(tmp_path: Path) -> None:
    path = str(tmp_path / 'h.sqlite')
    history = TaskHistory(path)
    for index in range(500):
        history.write(ended(f't{index}'))
    reader = sqlite3.connect(path)

    assert reader.execute('SELECT count(*) FROM tasks').fetchone()[0] == 0
    history.flush()
    assert reader.execute('SELECT count(*) FROM tasks').fetchone()[0] == 500
    assert history.pending == 0


def test_a_query_sees_the_changes_not_yet_flushed(tmp_path: Path) -> None:
    # a task that has just ended has left the registry: GetTaskStates must find it here
    path = str(tmp_path / 'h.sqlite')
    history = TaskHistory(path)
    history.write(ended('t1'))

    rows = history.query(HistoryQuery(task_id='t1', limit=1))

    assert [(row.task_id, row.status) for row in rows] == [('t1', 'DONE')]
    assert history.pending == 0
    assert sqlite3.connect(path).execute('SELECT count(*) FROM tasks').fetchone()[0] == 1


def test_sequences_only_grow_across_restarts_and_an_id_may_come_again(tmp_path: Path) -> None:
    path = str(tmp_path / 'h.sqlite')
    first = TaskHistory(path)
    first.write(ended('same'))
    first.flush()
    first.close()
    second = TaskHistory(path)
    second.write(ended('same'))
    second.flush()

    rows = second.query(HistoryQuery(oldest_first=True))
    assert [(r.task_id, r.sequence) for r in rows] == [('same', 1), ('same', 2)]


def test_a_sequence_is_never_given_again_once_retention_deleted_every_ended_task(
    tmp_path: Path,
) -> None:
    """A robot idle longer than the age kept: its next start deletes every ended row, and the
    next result still follows the last one the cloud has (not 1, which it has had)."""
    path = str(tmp_path / 'h.sqlite')
    first = TaskHistory(path)
    for index in range(3):
        first.write(ended(f'old{index}', at=1000.0))
    first.flush()
    first.close()
    second = TaskHistory(path)
    assert second.prune(max_results=0, max_age_days=1, now=1000.0 + 2 * 86400) == 3
    second.close()
    third = TaskHistory(path)

    assert third.write(ended('new')) == 4
    third.flush()
    assert [(r.task_id, r.sequence) for r in third.query(HistoryQuery())] == [('new', 4)]


def test_tasks_left_unfinished_by_a_crash_are_closed_once_at_the_next_start(
    tmp_path: Path,
) -> None:
    path = str(tmp_path / 'h.sqlite')
    crashed = TaskHistory(path)
    running = TaskRecord('running', NAV, 'CLOUD', received_at=5.0)
    running.mark_started(now=6.0)
    crashed.write(running)
    crashed.write(ended('done'))
    crashed.flush()
    crashed._lock.close()  # type: ignore[union-attr]  # the process dies: no close(), and
    # its lock on the file goes with it

    restarted = TaskHistory(path)
    closed = restarted.close_unfinished('the Task Manager restarted while it ran', now=50.0)
    restarted.close()
    again = TaskHistory(path).close_unfinished('twice?')

    assert [(r.task_id, r.status, r.ended, r.sequence) for r in closed] == [
        ('running', 'ERROR', 50.0, 2)
    ]
    assert json.loads(closed[0].result or '') == {
        'error': 'the Task Manager restarted while it ran'
    }
    assert again == []
    stored = TaskHistory(path).query(HistoryQuery(task_name='nav'))
    assert [(r.task_id, r.status, r.started) for r in stored] == [('running', 'ERROR', 6.0)]


def test_queries_filter_and_page_by_sequence(tmp_path: Path) -> None:
    history = TaskHistory('')
    for index in range(6):
        record = ended(f'n{index}', NAV if index % 2 else FIB, at=100.0 + index)
        if index == 5:
            record = TaskRecord('n5', NAV, 'UI', received_at=104.0)
            record.mark_ended(TaskStatus.ERROR, {'error': 'x'}, ErrorCode.UNKNOWN_TASK, now=105.0)
        history.write(record)
    history.flush()

    def ids(**query: object) -> list[str]:
        return [row.task_id for row in history.query(HistoryQuery(**query))]  # type: ignore[arg-type]

    assert ids() == ['n5', 'n4', 'n3', 'n2', 'n1', 'n0']
    assert ids(task_name='nav') == ['n5', 'n3', 'n1']
    assert ids(status='ERROR') == ['n5']
    assert ids(source='UI') == ['n5']
    assert ids(ended_after=102.0, ended_before=104.0) == ['n3', 'n2']
    assert ids(after_sequence=4, oldest_first=True) == ['n4', 'n5']
    assert ids(limit=2) == ['n5', 'n4']


def test_retention_keeps_the_newest_and_drops_the_old(tmp_path: Path) -> None:
    history = TaskHistory('')
    for index in range(10):
        history.write(ended(f'r{index}', at=1000.0 + index * 86400))
    running = TaskRecord('running', FIB, 'CLI', received_at=0.0)
    history.write(running)
    history.flush()

    by_count = history.prune(max_results=6, max_age_days=0)
    by_age = history.prune(max_results=0, max_age_days=2.5, now=1000.0 + 9 * 86400)

    assert (by_count, by_age) == (4, 3)
    assert [r.task_id for r in history.query(HistoryQuery())] == ['r9', 'r8', 'r7']
    assert [r.task_id for r in history.unfinished()] == ['running']


def test_pruning_goes_in_batches_oldest_first() -> None:
    history = TaskHistory('')
    for index in range(10):
        history.write(ended(f'b{index}'))
    history.flush()

    deleted = [history.prune(max_results=3, max_age_days=0, batch=3) for _ in range(4)]

    assert deleted == [3, 3, 1, 0]
    assert [r.task_id for r in history.query(HistoryQuery())] == ['b9', 'b8', 'b7']


def test_a_file_that_is_not_a_database_is_refused(tmp_path: Path) -> None:
    path = tmp_path / 'h.sqlite'
    path.write_bytes(b'this is no SQLite file' * 100)

    with pytest.raises(HistoryError, match='is not a task history database'):
        TaskHistory(str(path))


def test_a_database_of_another_kind_or_a_newer_schema_is_refused(tmp_path: Path) -> None:
    other = tmp_path / 'other.sqlite'
    sqlite3.connect(other).execute('CREATE TABLE t (x)')
    newer = tmp_path / 'newer.sqlite'
    sqlite3.connect(newer).execute(f'PRAGMA user_version = {SCHEMA_VERSION + 1}')

    with pytest.raises(HistoryError, match='not a task history'):
        TaskHistory(str(other))
    with pytest.raises(HistoryError, match=f'schema version {SCHEMA_VERSION + 1}'):
        TaskHistory(str(newer))


def test_a_first_version_file_is_opened_and_upgraded(tmp_path: Path) -> None:
    path = tmp_path / 'v1.sqlite'
    database = sqlite3.connect(path)
    database.executescript(SCHEMA_V1_FILE)
    database.close()

    history = TaskHistory(str(path))
    history.write(ended('new'))
    history.flush()

    assert [(r.task_id, r.sequence) for r in history.query(HistoryQuery())] == [
        ('new', 2),
        ('old', 1),
    ]
    version = sqlite3.connect(path).execute('PRAGMA user_version').fetchone()[0]
    assert version == SCHEMA_VERSION
    old = history.query(HistoryQuery(task_name='fib', limit=2))[-1]
    assert (old.task_id, old.paused_sec, old.pauses) == ('old', 0.0, '[]')
    assert old.size == ROW_OVERHEAD_BYTES + 21  # version 4 measures the rows before it
    assert history.schedule_store().load() == ([], [])  # version 2 adds the schedules
    history.prune(max_results=0, max_age_days=1, now=10 * 86400.0)  # both rows deleted
    history.close()
    reopened = TaskHistory(str(path))
    assert reopened.write(ended('newer')) == 3  # version 5 kept the last sequence given
    reopened.close()


def test_a_paused_task_is_stored_with_its_pauses_and_paused_time(tmp_path: Path) -> None:
    history = TaskHistory(str(tmp_path / 'h.sqlite'))
    record = TaskRecord('t1', FIB, 'CLOUD', received_at=10.0)
    record.mark_started(now=11.0)
    record.mark_paused('operator', now=12.0)
    record.mark_resumed('UI', now=14.5)
    record.mark_ended(TaskStatus.DONE, now=20.0)
    history.write(record)
    history.flush()

    (row,) = history.query(HistoryQuery())
    assert row.paused_sec == 2.5
    assert json.loads(row.pauses) == [
        {'paused': 12.0, 'paused_by': 'operator', 'resumed': 14.5, 'resumed_by': 'UI'}
    ]


def test_a_second_store_on_the_same_file_is_refused_until_the_first_closes(tmp_path: Path) -> None:
    path = str(tmp_path / 'history.sqlite')
    first = TaskHistory(path)

    with pytest.raises(HistoryInUseError, match=f'pid {os.getpid()}'):
        TaskHistory(path)
    first.close()
    TaskHistory(path).close()


def test_a_large_task_data_and_result_are_kept_as_a_note_of_their_size() -> None:
    history = TaskHistory('')
    big_data = json.dumps({'blob': 'é' * HISTORY_TASK_DATA_MAX_BYTES})
    record = TaskRecord('big', FIB, 'CLI', task_data=big_data, received_at=1.0)
    record.mark_started(now=2.0)
    record.mark_ended(TaskStatus.DONE, {'blob': 'x' * HISTORY_RESULT_MAX_BYTES}, now=3.0)
    history.write(record)
    history.write(ended('small', order=[1, 2]))
    history.flush()

    big, small = history.query(HistoryQuery(oldest_first=True))

    assert json.loads(big.task_data) == {'omitted_bytes': len(big_data.encode())}
    assert json.loads(big.result or '') == {'omitted_bytes': HISTORY_RESULT_MAX_BYTES + 11}
    assert big.size < 1000
    assert (small.task_data, json.loads(small.result or '')) == ('{"order": 1}', {'order': [1, 2]})


def test_sixty_starts_of_900_kb_add_less_than_a_megabyte(tmp_path: Path) -> None:
    path = tmp_path / 'h.sqlite'
    history = TaskHistory(str(path))
    data = json.dumps({'blob': 'x' * 900_000})
    for index in range(60):
        history.write(TaskRecord(f's{index}', FIB, 'CLI', task_data=data, received_at=1.0))
    history.flush()
    history.close()

    size = sum(os.path.getsize(f) for f in tmp_path.iterdir() if f.name.startswith('h.sqlite'))
    assert size < 1_000_000  # 57 MB before


def test_retention_bounds_the_bytes_of_the_ended_tasks(tmp_path: Path) -> None:
    history = TaskHistory(str(tmp_path / 'h.sqlite'))
    for index in range(10):
        history.write(ended(f'r{index}', at=100.0 + index, blob='x' * 1000))
    running = TaskRecord('running', FIB, 'CLI', task_data='x' * 5000, received_at=0.0)
    history.write(running)
    history.flush()
    row_bytes = history.ended_bytes // 10

    deleted = history.prune(max_results=0, max_age_days=0, max_bytes=row_bytes * 4 + 10)

    assert deleted == 6
    assert [r.task_id for r in history.query(HistoryQuery())] == ['r9', 'r8', 'r7', 'r6']
    assert history.ended_bytes == row_bytes * 4
    assert [r.task_id for r in history.unfinished()] == ['running']
    history.close()
    reopened = TaskHistory(str(tmp_path / 'h.sqlite'))
    assert reopened.ended_bytes == row_bytes * 4  # the rows' sizes, read back


def test_retention_by_bytes_goes_in_batches_and_counts_every_deletion() -> None:
    history = TaskHistory('')
    for index in range(10):
        history.write(ended(f'b{index}', blob='x' * 500))
    history.flush()
    row_bytes = history.ended_bytes // 10

    deleted = [history.prune(0, 0, batch=3, max_bytes=row_bytes * 3) for _ in range(4)]
    by_count = history.prune(max_results=2, max_age_days=0)

    assert (deleted, by_count) == ([3, 3, 1, 0], 1)
    assert history.ended_bytes == row_bytes * 2


def test_tasks_closed_at_start_count_in_the_bytes(tmp_path: Path) -> None:
    path = str(tmp_path / 'h.sqlite')
    history = TaskHistory(path)
    history.write(TaskRecord('crashed', FIB, 'CLI', task_data='{}', received_at=1.0))
    history.flush()
    history.close()

    reopened = TaskHistory(path)
    assert reopened.ended_bytes == 0
    closed = reopened.close_unfinished('the node stopped')

    assert reopened.ended_bytes == closed[0].size > ROW_OVERHEAD_BYTES
    assert reopened.query(HistoryQuery())[0].size == closed[0].size
