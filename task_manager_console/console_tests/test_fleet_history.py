"""The fleet history on SQLite and on a real PostgreSQL server: each result stored once by its
robot, sequence and task, the filters, what is refused, and the schema's migrations."""

import threading
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import create_engine, inspect, text

from task_manager.core.bounds import FLEET_HISTORY_ROWS_MAX, HISTORY_RESULT_MAX_BYTES
from task_manager.core.text.request_text import REFUSED, is_refused_character
from task_manager_console.store import fleet_history
from task_manager_console.store.fleet_history import (
    DatabaseUnavailable,
    FleetHistory,
    HistoryFilter,
    head_revision,
    upgrade,
)
from task_manager_console.store.local_postgres import PostgresServer
from task_manager_console.store.rows import BadResultError
from task_manager_console.store.schema import metadata

START = datetime(2026, 1, 1, 12, 0, tzinfo=UTC)


def task(sequence: int, **fields: Any) -> dict[str, Any]:
    """A robot's result (Task document) ended `sequence` minutes after START."""
    ended = START + timedelta(minutes=sequence)
    return {
        'task_id': f'task-{sequence}',
        'task_name': 'fib',
        'source': 'CLOUD',
        'status': 'DONE',
        'error_code': '',
        'received': (ended - timedelta(seconds=2)).isoformat(),
        'started': (ended - timedelta(seconds=1)).isoformat(),
        'ended': ended.isoformat(),
        'result': {'sequence': [0, 1, 1, 2]},
        'sequence': sequence,
        'priority': 3,
        'attempt': 1,
        'decisions': [{'at': ended.isoformat(), 'decision': 'started', 'reason': 'free'}],
        **fields,
    }


def keys(documents: list[dict[str, Any]]) -> list[tuple[str, int]]:
    return [(d['robot_id'], d['sequence']) for d in documents]


def test_a_result_is_stored_once_by_robot_sequence_and_task(history: FleetHistory) -> None:
    assert history.store('robot1', task(1)) is True
    assert history.store('robot1', task(1)) is False  # delivered again
    assert history.store('robot2', task(1)) is True  # another robot's sequence 1
    assert history.store_many([('robot1', task(2)), ('robot1', task(2)), ('robot1', task(1))]) == [
        True,
        False,
        False,
    ]
    assert history.count() == 3
    assert history.count('robot1') == 2


def test_a_robot_whose_history_began_again_has_its_new_results_stored(
    history: FleetHistory,
) -> None:
    """Reinstalled, a robot numbers its results from 1 again, with other tasks."""
    assert history.store_many([('robot1', task(n)) for n in (1, 2)]) == [True, True]
    again = [('robot1', task(n, task_id=f'new-{n}')) for n in (1, 2, 2)]
    assert history.store_many(again) == [True, True, False]
    assert history.count('robot1') == 4


def test_a_batch_partly_stored_before_says_which_of_it_are_new(history: FleetHistory) -> None:
    """A batch none of which was stored goes in one insert; one that holds results stored
    before is stored again in the way that says which are new."""
    assert history.store_many([('robot1', task(n)) for n in (1, 2)]) == [True, True]
    again = [('robot1', task(n)) for n in range(1, 6)]
    assert history.store_many(again) == [False, False, True, True, True]
    assert history.count() == 5


def test_a_stored_result_reads_back_as_it_came(history: FleetHistory) -> None:
    sent = task(7, mission_id='mission-1', error_message='', duration_sec=1.5, paused_sec=0.0)
    history.store('robot1', sent)
    [stored] = history.query(HistoryFilter())
    for field in ('task_id', 'task_name', 'source', 'status', 'error_code', 'sequence', 'result'):
        assert stored[field] == sent[field], field
    for stamp in ('received', 'started', 'ended'):
        assert datetime.fromisoformat(stored[stamp]) == datetime.fromisoformat(sent[stamp])
    assert stored['robot_id'] == 'robot1'
    assert stored['mission_id'] == 'mission-1'
    assert stored['decisions'] == sent['decisions']
    assert (stored['priority'], stored['attempt'], stored['duration_sec']) == (3, 1, 1.5)
    assert datetime.fromisoformat(stored['stored_at']) <= datetime.now(UTC)


def test_queries_filter_and_come_newest_first(history: FleetHistory) -> None:
    history.store_many([('robot1', task(n)) for n in range(1, 6)])
    history.store_many(
        [
            ('robot2', task(10, task_name='dock', status='ERROR', error_code='timeout')),
            ('robot2', task(11, source='WEB:alice')),
        ]
    )
    everything = history.query(HistoryFilter())
    assert [d['sequence'] for d in everything] == [11, 10, 5, 4, 3, 2, 1]
    assert keys(history.query(HistoryFilter(robot_id='robot2'))) == [('robot2', 11), ('robot2', 10)]
    assert keys(history.query(HistoryFilter(task_id='task-3'))) == [('robot1', 3)]
    assert keys(history.query(HistoryFilter(task_name='dock'))) == [('robot2', 10)]
    assert keys(history.query(HistoryFilter(status='ERROR'))) == [('robot2', 10)]
    assert keys(history.query(HistoryFilter(source='WEB:alice'))) == [('robot2', 11)]
    window = HistoryFilter(
        ended_after=START + timedelta(minutes=2), ended_before=START + timedelta(minutes=4)
    )
    assert keys(history.query(window)) == [('robot1', 3), ('robot1', 2)]  # after: inclusive
    assert keys(history.query(HistoryFilter(robot_id='robot1', limit=2))) == [
        ('robot1', 5),
        ('robot1', 4),
    ]
    assert history.last_result('robot1') == everything[2]
    assert history.last_result('robot9') is None


@pytest.mark.parametrize(
    ('where', 'message'),
    [
        (HistoryFilter(limit=0), f'limit must be from 1 to {FLEET_HISTORY_ROWS_MAX}, got 0'),
        (
            HistoryFilter(limit=FLEET_HISTORY_ROWS_MAX + 1),
            f'limit must be from 1 to {FLEET_HISTORY_ROWS_MAX}, got {FLEET_HISTORY_ROWS_MAX + 1}',
        ),
        (HistoryFilter(robot_id='robot\n1'), 'robot_id contains the character U+000A'),
        (HistoryFilter(task_name='fib\x00'), 'task_name contains the character U+0000'),
    ],
)
def test_a_query_beyond_the_bounds_is_refused(
    history: FleetHistory, where: HistoryFilter, message: str
) -> None:
    with pytest.raises(ValueError, match=message.replace('+', r'\+')):
        history.query(where)


@pytest.mark.parametrize(
    ('robot_id', 'fields', 'why'),
    [
        ('robot\x1b1', {}, 'robot_id contains the character U+001B'),
        ('robot1', {'task_name': 'fib\nINFO forged'}, 'task_name contains the character U+000A'),
        ('robot1', {'task_id': 'a\u202eb'}, 'task_id contains the character U+202E'),
        ('robot1', {'task_name': 'n' * 257}, 'task_name has 257 characters; at most 256'),
        ('robot1', {'sequence': 0}, 'sequence must be a positive integer, got 0'),
        ('robot1', {'sequence': '3'}, "sequence must be a positive integer, got '3'"),
        ('robot1', {'sequence': True}, 'sequence must be a positive integer, got True'),
        ('robot1', {'status': 7}, 'status must be text, got int'),
        ('robot1', {'task_id': ''}, 'task_id is missing'),
        ('robot1', {'ended': 'yesterday'}, "ended must be an ISO 8601 time, got 'yesterday'"),
    ],
)
def test_a_result_that_cannot_be_a_row_is_refused_and_nothing_is_stored(
    history: FleetHistory, robot_id: str, fields: dict[str, Any], why: str
) -> None:
    with pytest.raises(BadResultError, match=why.replace('+', r'\+')):
        history.store_many([('robot1', task(1)), (robot_id, {**task(2), **fields})])
    assert history.count() == 0


def test_a_large_result_is_kept_as_its_size(history: FleetHistory) -> None:
    large = {'blob': 'x' * HISTORY_RESULT_MAX_BYTES}
    history.store('robot1', task(1, result=large))
    [stored] = history.query(HistoryFilter())
    assert stored['result'] == {'omitted_bytes': HISTORY_RESULT_MAX_BYTES + len('{"blob":""}')}


def test_results_stored_at_once_from_two_threads_are_each_stored_once(
    history: FleetHistory,
) -> None:
    """Two writers (a console restarted while the old one still stores, say) of the same
    results, in batches that overlap: every result once, and each is new to exactly one."""
    results = [('robot1', task(n)) for n in range(1, 201)]
    new: list[list[bool]] = [[], []]

    def store(writer: int) -> None:
        for start in range(0, len(results), 20):
            new[writer] += history.store_many(results[start : start + 20])

    writers = [threading.Thread(target=store, args=(i,)) for i in (0, 1)]
    for writer in writers:
        writer.start()
    for writer in writers:
        writer.join()
    assert history.count() == 200
    assert [a + b for a, b in zip(new[0], new[1], strict=True)] == [1] * 200


def test_the_migrations_make_the_schema_of_schema_py(history: FleetHistory) -> None:
    with history.engine.connect() as connection:
        differences = compare_metadata(MigrationContext.configure(connection), metadata)
    assert differences == []
    assert history.revision() == head_revision()


def test_a_database_at_the_first_revision_is_upgraded_in_place(database_url: str) -> None:
    engine = create_engine(fleet_history.database_url(database_url))
    with engine.begin() as connection:
        upgrade(connection, '0001')
        connection.execute(
            text(
                'INSERT INTO results (robot_id, sequence, task_id, task_name, source, status, '
                "error_code, ended, parent_id, details, stored_at) VALUES ('robot1', 1, 'old', "
                "'fib', 'CLOUD', 'DONE', '', '2025-01-01 00:00:00', '', '{}', "
                "'2025-01-01 00:00:00')"
            )
        )
    assert 'ix_results_ended_id' not in {i['name'] for i in inspect(engine).get_indexes('results')}
    engine.dispose()

    history = FleetHistory.open(database_url)
    try:
        assert history.revision() == head_revision() == '0004'
        indexes = {i['name'] for i in inspect(history.engine).get_indexes('results')}
        assert {'ix_results_ended_id', 'ix_results_task_name_ended_id'} <= indexes
        assert 'ix_results_task_name_ended' not in indexes  # 0002's, made again by 0003
        assert [d['task_id'] for d in history.query(HistoryFilter())] == ['old']
        assert history.store('robot1', task(1, task_id='old')) is False  # the key held
        assert history.store('robot1', task(1)) is True  # another task: 0004's key
    finally:
        history.close()


def test_opening_a_database_at_the_newest_revision_changes_nothing(database_url: str) -> None:
    first = FleetHistory.open(database_url)
    first.store('robot1', task(1))
    first.close()
    again = FleetHistory.open(database_url)
    try:
        with again.engine.connect() as connection:
            versions = connection.execute(text('SELECT version_num FROM alembic_version')).all()
        assert versions == [(head_revision(),)]
        assert again.count() == 1
    finally:
        again.close()


@pytest.fixture
def closed_port() -> Iterator[int]:
    from task_manager_mqtt.broker import free_port

    yield free_port()


def test_a_database_that_cannot_be_reached_is_one_line(closed_port: int, tmp_path: Path) -> None:
    url = f'postgresql://console:secret@127.0.0.1:{closed_port}/fleet'
    with pytest.raises(DatabaseUnavailable) as refused:
        FleetHistory.open(url)
    message = str(refused.value)
    assert message.startswith(
        f'cannot open the fleet history at postgresql+psycopg://console:***@127.0.0.1:'
        f'{closed_port}/fleet: '
    ), message
    assert 'secret' not in message
    assert '\n' not in message

    (tmp_path / 'a_file').write_text('')
    with pytest.raises(DatabaseUnavailable, match='cannot open the fleet history at sqlite'):
        FleetHistory.open(f'sqlite:///{tmp_path / "a_file" / "fleet.sqlite"}')
    with pytest.raises(DatabaseUnavailable, match=r'on SQLite \(sqlite:///path\) or PostgreSQL'):
        FleetHistory.open('mysql://127.0.0.1/fleet')
    with pytest.raises(DatabaseUnavailable, match='is no database URL'):
        FleetHistory.open('not a url')


def test_a_postgresql_server_that_stops_is_unavailable_then_stores_again(
    postgres: PostgresServer,
) -> None:
    history = FleetHistory.open(postgres.create_database('fleet_outage'))
    try:
        history.store('robot1', task(1))
        postgres.stop()
        try:
            with pytest.raises(DatabaseUnavailable, match='cannot store in postgresql'):
                history.store('robot1', task(2))
        finally:
            postgres.start()
        assert history.store('robot1', task(2)) is True
        assert history.count() == 2
    finally:
        history.close()


def test_the_quick_check_of_a_rows_text_refuses_what_text_problem_refuses() -> None:
    refused = [c for c in map(chr, range(0x110000)) if is_refused_character(c)]
    assert [c for c in map(chr, range(0x110000)) if REFUSED.search(c)] == refused
