"""ScheduleStore: the schedules table in an in-memory SQLite database."""

import contextlib
import json
import sqlite3
from collections.abc import Iterator
from typing import Any

import pytest

from task_manager.core.schedules.book import ScheduleState
from task_manager.core.schedules.schedule import OverlapPolicy, ScheduleSpec
from task_manager.core.schedules.store import SCHEDULES_SCHEMA, ScheduleStore

T0 = 1_767_225_600.0


class Transactions:
    """BEGIN IMMEDIATE ... COMMIT, or ROLLBACK on an error (as the history's), counted."""

    def __init__(self, db: sqlite3.Connection) -> None:
        self.db = db
        self.count = 0

    @contextlib.contextmanager
    def __call__(self) -> Iterator[None]:
        self.count += 1
        self.db.execute('BEGIN IMMEDIATE')
        try:
            yield
        except BaseException:
            self.db.execute('ROLLBACK')
            raise
        self.db.execute('COMMIT')


@pytest.fixture
def db() -> Iterator[sqlite3.Connection]:
    connection = sqlite3.connect(':memory:', isolation_level=None)
    for statement in filter(str.strip, SCHEDULES_SCHEMA.split(';')):
        connection.execute(statement)
    yield connection
    connection.close()


@pytest.fixture
def transactions(db: sqlite3.Connection) -> Transactions:
    return Transactions(db)


@pytest.fixture
def store(db: sqlite3.Connection, transactions: Transactions) -> ScheduleStore:
    return ScheduleStore(db, transactions)


def spec(schedule_id: str, **when: Any) -> ScheduleSpec:
    return ScheduleSpec(
        schedule_id, 'patrol', '{"zone": 1}', 'cli', T0, **(when or {'period_sec': 60})
    )


def test_schedules_load_as_saved_in_creation_order(store: ScheduleStore) -> None:
    saved = [
        (spec('z', cron='0 2 * * *', time_zone='Europe/Paris'), ScheduleState(next_run=T0 + 1)),
        (spec('a', at=T0 + 5), ScheduleState(enabled=False, next_run=None, missed_count=2)),
        (spec('m'), ScheduleState(next_run=T0 + 60.25, last_task_id='m-run-1', run_count=1)),
    ]
    for s, state in saved:
        store.save(s, state)

    assert store.load() == (saved, [])


def test_saving_a_stored_schedule_again_replaces_it_in_place(store: ScheduleStore) -> None:
    for key in ('a', 'b', 'c'):
        store.save(spec(key), ScheduleState(next_run=T0))
    changed = ScheduleSpec('a', 'dock', '{}', 'web', T0, at=T0, overlap=OverlapPolicy.ALLOW_ALL)
    store.save(changed, ScheduleState(run_count=3))

    schedules, _ = store.load()

    assert [s.schedule_id for s, _ in schedules] == ['a', 'b', 'c']
    assert schedules[0] == (changed, ScheduleState(run_count=3))


def test_many_states_are_saved_in_one_transaction(
    store: ScheduleStore, transactions: Transactions
) -> None:
    for n in range(100):
        store.save(spec(f's{n}'), ScheduleState(next_run=T0))
    before = transactions.count

    store.save_states([(f's{n}', ScheduleState(next_run=T0 + n, run_count=n)) for n in range(100)])

    assert transactions.count == before + 1
    schedules, _ = store.load()
    assert [state.run_count for _, state in schedules] == list(range(100))


def test_states_that_fail_to_save_leave_every_state_as_it_was(
    db: sqlite3.Connection, store: ScheduleStore
) -> None:
    store.save(spec('a'), ScheduleState(next_run=T0))
    store.save(spec('b'), ScheduleState(next_run=T0))
    db.execute(
        "CREATE TRIGGER fail BEFORE UPDATE ON schedules WHEN NEW.schedule_id = 'b' "
        "BEGIN SELECT RAISE(ABORT, 'disk trouble'); END"
    )

    with pytest.raises(sqlite3.DatabaseError, match='disk trouble'):
        store.save_states([('a', ScheduleState(run_count=1)), ('b', ScheduleState(run_count=1))])

    assert [state.run_count for _, state in store.load()[0]] == [0, 0]


def test_states_of_schedules_no_longer_stored_are_ignored(store: ScheduleStore) -> None:
    store.save(spec('a'), ScheduleState(next_run=T0))
    store.save_states([('gone', ScheduleState(run_count=5)), ('a', ScheduleState(run_count=1))])
    assert store.load() == ([(spec('a'), ScheduleState(run_count=1))], [])


def test_nothing_to_save_or_delete_opens_no_transaction(
    store: ScheduleStore, transactions: Transactions
) -> None:
    store.save_states([])
    store.delete([])
    assert transactions.count == 0


def test_deleted_schedules_are_gone(store: ScheduleStore) -> None:
    for key in ('a', 'b', 'c'):
        store.save(spec(key), ScheduleState())
    store.delete(['a', 'c', 'never-stored'])
    assert [s.schedule_id for s, _ in store.load()[0]] == ['b']


def test_a_row_that_cannot_be_read_is_reported_skipped_and_kept(
    db: sqlite3.Connection, store: ScheduleStore
) -> None:
    store.save(spec('good'), ScheduleState())
    newer = spec('newer').to_json()[:-1] + ',"priority":3}'  # a field from a newer version
    rows = [
        ('corrupt', '{"schedule_id": "corr', ScheduleState().to_json()),
        ('newer', newer, ScheduleState().to_json()),
        ('bad-state', spec('bad-state').to_json(), '{"enabled": "yes"}'),
        ('renamed', spec('other').to_json(), ScheduleState().to_json()),
    ]
    for position, (key, spec_text, state_text) in enumerate(rows, start=2):
        db.execute(
            'INSERT INTO schedules VALUES (?, ?, ?, ?)', (key, spec_text, state_text, position)
        )

    schedules, bad = store.load()

    assert schedules == [(spec('good'), ScheduleState())]
    assert [schedule_id for schedule_id, _ in bad] == ['corrupt', 'newer', 'bad-state', 'renamed']
    assert "its spec names another schedule, 'other'" in dict(bad)['renamed']
    assert db.execute('SELECT count(*) FROM schedules').fetchone()[0] == 5


@pytest.mark.parametrize(
    ('field', 'value', 'why'),
    [
        ('period_sec', 1e300, 'period_sec must be from 0.1 to 31622400 s, got 1e+300'),
        ('period_sec', 0.001, 'period_sec must be from 0.1 to 31622400 s, got 0.001'),
        ('misfire_grace_sec', 1e300, 'misfire_grace_sec must be from 0 to 604800 s, got 1e+300'),
        ('start', 1e300, 'start must be from 0 to 253402300799 s, got 1e+300'),
        ('options', {'priority': 2**40}, 'options: priority must be from -2147483648'),
    ],
)
def test_a_stored_schedule_outside_the_bounds_is_set_aside_with_why(
    db: sqlite3.Connection, store: ScheduleStore, field: str, value: Any, why: str
) -> None:
    """An older version stored such schedules; every read of them crashed the node."""
    stored = json.loads(spec('old').to_json())
    stored[field] = value
    db.execute(
        'INSERT INTO schedules VALUES (?, ?, ?, ?)',
        ('old', json.dumps(stored), ScheduleState().to_json(), 1),
    )

    schedules, bad = store.load()

    assert schedules == []
    assert [schedule_id for schedule_id, _ in bad] == ['old']
    assert bad[0][1].startswith(why)
