"""The schedules on disk: one SQLite row per schedule, its spec and its state as JSON text.

The table lives in the task history's file and connection (autocommit mode); the caller
passes the history's transaction, so every write here is one BEGIN IMMEDIATE ... COMMIT.
"""

import sqlite3
from collections.abc import Callable, Iterable
from contextlib import AbstractContextManager

from task_manager.core.schedules.book import ScheduleState
from task_manager.core.schedules.schedule import ScheduleSpec

# One or more ';'-separated statements, for the history's migrations.
SCHEDULES_SCHEMA = """
CREATE TABLE schedules (
    schedule_id TEXT PRIMARY KEY,
    spec TEXT NOT NULL,
    state TEXT NOT NULL,
    position INTEGER NOT NULL
);
CREATE INDEX schedules_by_position ON schedules (position)
"""

# A new schedule goes after every other (position keeps creation order); an existing one keeps
# its position.
_UPSERT = (
    'INSERT INTO schedules (schedule_id, spec, state, position) '
    'VALUES (?, ?, ?, (SELECT coalesce(max(position), 0) + 1 FROM schedules)) '
    'ON CONFLICT (schedule_id) DO UPDATE SET spec = excluded.spec, state = excluded.state'
)

Transaction = Callable[[], AbstractContextManager[None]]


class ScheduleStore:
    """Reads and writes the schedules table."""

    def __init__(self, db: sqlite3.Connection, transaction: Transaction) -> None:
        """`db` is in autocommit mode; `transaction()` wraps writes in one transaction."""
        self._db = db
        self._transaction = transaction

    def load(self) -> tuple[list[tuple[ScheduleSpec, ScheduleState]], list[tuple[str, str]]]:
        """Every stored schedule in creation order, and the rows that cannot be run: (id, why).

        A row that cannot be read (corrupt, written by a newer version, or outside the bounds
        of core/bounds.py, as an older version could store) is left as it is, so the version
        that wrote it can still use it; the caller reports it.
        """
        schedules: list[tuple[ScheduleSpec, ScheduleState]] = []
        bad: list[tuple[str, str]] = []
        rows = self._db.execute('SELECT schedule_id, spec, state FROM schedules ORDER BY position')
        for schedule_id, spec_text, state_text in rows:
            try:
                spec = ScheduleSpec.from_json(spec_text)
                state = ScheduleState.from_json(state_text)
            except (ValueError, TypeError) as error:  # json's and ScheduleError are ValueErrors
                bad.append((schedule_id, str(error)))
                continue
            if spec.schedule_id != schedule_id:
                bad.append((schedule_id, f'its spec names another schedule, {spec.schedule_id!r}'))
                continue
            schedules.append((spec, state))
        return schedules, bad

    def save(self, spec: ScheduleSpec, state: ScheduleState) -> None:
        """Insert a schedule, or replace the spec and state of a stored one."""
        with self._transaction():
            self._db.execute(_UPSERT, (spec.schedule_id, spec.to_json(), state.to_json()))

    def save_states(self, items: Iterable[tuple[str, ScheduleState]]) -> None:
        """Write many states in one transaction (a burst of firings is one commit).

        Ids that are not stored (removed meanwhile) are ignored.
        """
        rows = [(state.to_json(), schedule_id) for schedule_id, state in items]
        if not rows:
            return
        with self._transaction():
            self._db.executemany('UPDATE schedules SET state = ? WHERE schedule_id = ?', rows)

    def delete(self, schedule_ids: Iterable[str]) -> None:
        rows = [(schedule_id,) for schedule_id in schedule_ids]
        if not rows:
            return
        with self._transaction():
            self._db.executemany('DELETE FROM schedules WHERE schedule_id = ?', rows)
