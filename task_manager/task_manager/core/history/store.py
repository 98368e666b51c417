"""The durable task history: every request, its stamps, data, result and end, in SQLite.

One row per request (a task id may be used again once its task has ended, so rows have their
own `entry` number). A row keeps at most HISTORY_TASK_DATA_MAX_BYTES of the request's
task_data and HISTORY_RESULT_MAX_BYTES of its result: a larger one is kept as
`{"omitted_bytes": N}`. Each row knows its `size` in bytes, so that retention can bound the
bytes of the ended tasks as well as their number and age.

Changes are buffered and written by `flush`, one transaction for all the changes of one
executor turn, so a burst of 500 results is one commit, not 500. Each ended task gets a
`sequence` number that only grows, so a consumer can ask for "everything after N", and that is
never given again by this file: the last one given is kept beside the rows, so that retention
deleting every ended row (a robot idle longer than the age kept) does not start them again at
1, where the MQTT bridge and the fleet's history would take them for results already had.

The file uses WAL journaling: readers never block the writer. Nothing here knows ROS.
"""

import contextlib
import dataclasses
import fcntl
import os
import sqlite3
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from task_manager.core.history.rows import (
    COLUMNS,
    ROW_OVERHEAD_BYTES,
    TEXT_COLUMNS,
    HistoryRow,
    row_of,
    row_size,
)
from task_manager.core.schedules.store import SCHEDULES_SCHEMA, ScheduleStore
from task_manager.core.task import TaskRecord
from task_manager.core.text.json_text import compact_json

SCHEMA_VERSION = 5
MEMORY = ':memory:'

_SCHEMA_V1 = """
CREATE TABLE tasks (
    entry INTEGER PRIMARY KEY,
    task_id TEXT NOT NULL,
    task_name TEXT NOT NULL,
    source TEXT NOT NULL,
    mission_id TEXT NOT NULL,
    task_data TEXT NOT NULL,
    status TEXT NOT NULL,
    error_code TEXT NOT NULL,
    result TEXT,
    received REAL NOT NULL,
    started REAL,
    ended REAL,
    sequence INTEGER UNIQUE
);
CREATE INDEX tasks_unfinished ON tasks (entry) WHERE sequence IS NULL;
CREATE INDEX tasks_by_name ON tasks (task_name, sequence);
CREATE INDEX tasks_by_end ON tasks (ended);
"""

# Version 2: each task's pauses (system/pause) and the time it spent paused; the schedules.
_SCHEMA_V2 = (
    """
ALTER TABLE tasks ADD COLUMN paused_sec REAL NOT NULL DEFAULT 0;
ALTER TABLE tasks ADD COLUMN pauses TEXT NOT NULL DEFAULT '[]';
"""
    + SCHEDULES_SCHEMA
)

# Version 3: each task's priority, attempts and the decisions taken about it (issue 29).
_SCHEMA_V3 = """
ALTER TABLE tasks ADD COLUMN priority INTEGER NOT NULL DEFAULT 0;
ALTER TABLE tasks ADD COLUMN attempt INTEGER NOT NULL DEFAULT 1;
ALTER TABLE tasks ADD COLUMN decisions TEXT NOT NULL DEFAULT '[]';
"""

# Version 4: each row's size in bytes (issue 37), of the rows before measured here.
_SCHEMA_V4 = f"""
ALTER TABLE tasks ADD COLUMN size INTEGER NOT NULL DEFAULT 0;
UPDATE tasks SET size = {ROW_OVERHEAD_BYTES} + {
    ' + '.join(f'coalesce(length(CAST({c} AS BLOB)), 0)' for c in TEXT_COLUMNS)
}
"""

# Version 5: the last sequence number given, which retention may have deleted the row of.
_SCHEMA_V5 = """
CREATE TABLE last_sequence (value INTEGER NOT NULL);
INSERT INTO last_sequence SELECT coalesce(max(sequence), 0) FROM tasks
"""

# Each step upgrades the schema from the version before it; index 0 creates version 1.
_MIGRATIONS = (_SCHEMA_V1, _SCHEMA_V2, _SCHEMA_V3, _SCHEMA_V4, _SCHEMA_V5)


class HistoryError(Exception):
    """The history file cannot be used (not a database, or of an unknown schema)."""


class HistoryInUseError(Exception):
    """Another running Task Manager writes this history file (it holds `<file>.lock`)."""


def lock_history(path: str) -> IO[str]:
    """Hold an exclusive lock on `<path>.lock` while the store is open (our pid in it).

    Two nodes writing one file would both number results; the lock goes with the process, so
    a node that was killed leaves none behind.
    """
    lock = open(f'{path}.lock', 'a+')  # noqa: SIM115  (held until close())
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.seek(0)
        holder = lock.read().strip() or 'unknown'
        lock.close()
        raise HistoryInUseError(
            f'it is in use by another running Task Manager (pid {holder}); '
            'give each Task Manager its own history_path'
        ) from None
    lock.seek(0)
    lock.truncate()
    lock.write(f'{os.getpid()}\n')
    lock.flush()
    return lock


_UPSERT = (
    f'INSERT INTO tasks ({", ".join(COLUMNS)}) VALUES ({", ".join("?" for _ in COLUMNS)}) '
    'ON CONFLICT (entry) DO UPDATE SET '
    + ', '.join(f'{c} = excluded.{c}' for c in COLUMNS if c != 'entry')
)


@dataclass(frozen=True)
class HistoryQuery:
    """Which ended tasks to return; empty fields do not filter."""

    task_id: str = ''
    task_name: str = ''
    status: str = ''
    source: str = ''
    mission_id: str = ''
    ended_after: float | None = None
    ended_before: float | None = None
    after_sequence: int = 0
    limit: int = 100
    oldest_first: bool = False
    """By sequence, oldest first (to resume after a sequence number); else newest first."""

    def where(self) -> tuple[str, list[object]]:
        clauses, values = ['sequence IS NOT NULL'], []
        for column in ('task_id', 'task_name', 'status', 'source', 'mission_id'):
            if value := getattr(self, column):
                clauses.append(f'{column} = ?')
                values.append(value)
        if self.ended_after is not None:
            clauses.append('ended >= ?')
            values.append(self.ended_after)
        if self.ended_before is not None:
            clauses.append('ended < ?')
            values.append(self.ended_before)
        if self.after_sequence:
            clauses.append('sequence > ?')
            values.append(self.after_sequence)
        return ' AND '.join(clauses), values


class TaskHistory:
    """The history store of one Task Manager."""

    def __init__(self, path: str) -> None:
        """Open (or create) the store at `path`; '' or ':memory:' keeps it in memory only.

        Raises HistoryError when the file is not a database this version can use, and
        OSError / sqlite3.Error when it cannot be opened or written.
        """
        self.path = path or MEMORY
        self._lock: IO[str] | None = None
        if self.path != MEMORY:
            Path(self.path).parent.mkdir(parents=True, exist_ok=True)
            self._lock = lock_history(self.path)
        self._db = sqlite3.connect(self.path, isolation_level=None, check_same_thread=False)
        try:
            self._prepare()
        except sqlite3.DatabaseError as error:
            self.close()
            raise HistoryError(f'{self.path} is not a task history database ({error})') from None
        except HistoryError:
            self.close()
            raise
        self._next_entry = self._max('entry') + 1
        self._stored_sequence = int(
            self._db.execute('SELECT value FROM last_sequence').fetchone()[0]
        )
        """The last sequence number given, as the file holds it."""
        self._next_sequence = max(self._max('sequence'), self._stored_sequence) + 1
        self._ended_bytes = int(
            self._db.execute(
                'SELECT coalesce(sum(size), 0) FROM tasks WHERE sequence IS NOT NULL'
            ).fetchone()[0]
        )
        """The `size` of every ended row, those buffered included."""
        # key: record (by identity), value: its entry number, while it is not ended
        self._entries: dict[int, int] = {}
        # key: entry, value: the row to write at the next flush (later changes replace it)
        self._pending: dict[int, tuple[object, ...]] = {}

    def _prepare(self) -> None:
        self._db.execute('PRAGMA journal_mode = WAL')
        self._db.execute('PRAGMA synchronous = NORMAL')
        version = self._db.execute('PRAGMA user_version').fetchone()[0]
        if version > SCHEMA_VERSION:
            raise HistoryError(
                f'{self.path} has schema version {version}; this Task Manager knows up to '
                f'{SCHEMA_VERSION}'
            )
        if version == 0 and self._has_tables():
            raise HistoryError(f'{self.path} is a database, but not a task history')
        with self.transaction():
            for step in _MIGRATIONS[version:]:
                for statement in filter(str.strip, step.split(';')):
                    self._db.execute(statement)
            self._db.execute(f'PRAGMA user_version = {SCHEMA_VERSION}')

    def _has_tables(self) -> bool:
        return bool(self._db.execute("SELECT 1 FROM sqlite_master WHERE type = 'table'").fetchone())

    def _max(self, column: str) -> int:
        return int(self._db.execute(f'SELECT coalesce(max({column}), 0) FROM tasks').fetchone()[0])

    def transaction(self) -> '_Transaction':
        return _Transaction(self._db)

    def schedule_store(self) -> ScheduleStore:
        """The schedules, in the same file and connection."""
        return ScheduleStore(self._db, self.transaction)

    # ---- changes (buffered) -----------------------------------------------------------

    def write(self, record: TaskRecord) -> int | None:
        """Remember the record's current state for the next flush.

        Returns its sequence number once it has ended (assigned here, exactly once).
        """
        entry = self._entries.get(id(record))
        if entry is None:
            entry = self._next_entry
            self._next_entry += 1
            self._entries[id(record)] = entry
        sequence = None
        if record.is_final:
            del self._entries[id(record)]
            sequence = self._next_sequence
            self._next_sequence += 1
        row = self._pending[entry] = row_of(record, entry, sequence)
        if sequence is not None:
            self._ended_bytes += row[-1]  # type: ignore[operator]  # its size
        return sequence

    @property
    def ended_bytes(self) -> int:
        """The bytes of the ended tasks kept (their rows' `size`)."""
        return self._ended_bytes

    @property
    def pending(self) -> int:
        return len(self._pending)

    def flush(self) -> None:
        """Write every buffered change in one transaction; on failure they stay buffered."""
        if not self._pending:
            return
        rows = list(self._pending.values())
        with self.transaction():
            self._db.executemany(_UPSERT, rows)
            stored = self._store_last_sequence()
        self._stored_sequence = stored
        self._pending.clear()

    def _store_last_sequence(self) -> int:
        """Within a transaction: keep the last sequence number given, if it moved; it."""
        given = self._next_sequence - 1
        if given != self._stored_sequence:
            self._db.execute('UPDATE last_sequence SET value = ?', (given,))
        return given

    # ---- reading ----------------------------------------------------------------------

    def unfinished(self) -> list[HistoryRow]:
        """Requests that were received but never ended (the node died while they ran)."""
        return self._select('sequence IS NULL', [], 'entry', -1)

    def close_unfinished(self, reason: str, now: float | None = None) -> list[HistoryRow]:
        """End every unfinished request ERROR with `{"error": reason}`; returns them ended."""
        ended_at = time.time() if now is None else now
        closed = []
        result = compact_json({'error': reason})
        with self.transaction():
            for row in self.unfinished():
                sequence = self._next_sequence
                self._next_sequence += 1
                ended = dataclasses.replace(
                    row, status='ERROR', result=result, ended=ended_at, sequence=sequence
                )
                ended = dataclasses.replace(
                    ended, size=row_size(*(getattr(ended, c) for c in TEXT_COLUMNS))
                )
                self._db.execute(
                    'UPDATE tasks SET status = ?, result = ?, ended = ?, sequence = ?, size = ? '
                    'WHERE entry = ?',
                    ('ERROR', result, ended_at, sequence, ended.size, row.entry),
                )
                self._ended_bytes += ended.size
                closed.append(ended)
            stored = self._store_last_sequence()
        self._stored_sequence = stored
        return closed

    def query(self, query: HistoryQuery) -> list[HistoryRow]:
        """The rows asked for, buffered changes included: they are flushed first, so that a
        task that has just left the active ones is never missing from both (a flush that fails
        leaves them buffered, for the writer's next flush and its log line)."""
        with contextlib.suppress(sqlite3.Error):
            self.flush()
        where, values = query.where()
        order = 'sequence' if query.oldest_first else 'sequence DESC'
        return self._select(where, values, order, query.limit)

    def _select(self, where: str, values: list[object], order: str, limit: int) -> list[HistoryRow]:
        sql = f'SELECT {", ".join(COLUMNS)} FROM tasks WHERE {where} ORDER BY {order} LIMIT ?'
        return [HistoryRow(*row) for row in self._db.execute(sql, [*values, limit])]

    def prune(
        self,
        max_results: int,
        max_age_days: float,
        now: float | None = None,
        batch: int = 0,
        max_bytes: int = 0,
    ) -> int:
        """Delete the oldest ended tasks beyond the newest `max_results`, older than the age,
        or beyond `max_bytes` of ended rows (0: no such limit), at most `batch` of them (0:
        all); returns how many were deleted.

        Small batches keep each transaction short, so pruning never holds up dispatch.
        """
        conditions, values = [], []
        if max_bytes > 0 and self._ended_bytes > max_bytes:
            # the oldest rows whose sizes add up to the excess (rows still buffered are the
            # newest: they count in the excess, and are never deleted by it)
            excess, oldest = self._ended_bytes - max_bytes, None
            rows = self._db.execute(
                'SELECT sequence, size FROM tasks WHERE sequence IS NOT NULL ORDER BY sequence '
                'LIMIT ?',
                (batch or -1,),
            )
            for sequence, size in rows:
                oldest, excess = sequence, excess - size
                if excess <= 0:
                    break
            rows.close()
            if oldest is not None:
                conditions.append('sequence <= ?')
                values.append(oldest)
        if max_results > 0:
            row = self._db.execute(
                'SELECT sequence FROM tasks WHERE sequence IS NOT NULL '
                'ORDER BY sequence DESC LIMIT 1 OFFSET ?',
                (max_results,),
            ).fetchone()
            if row is not None:
                conditions.append('sequence <= ?')
                values.append(row[0])
        if max_age_days > 0:
            conditions.append('ended < ?')
            values.append((time.time() if now is None else now) - max_age_days * 86400)
        if not conditions:
            return 0
        selected = (
            f'SELECT entry FROM tasks WHERE sequence IS NOT NULL AND ({" OR ".join(conditions)}) '
            'ORDER BY sequence LIMIT ?'
        )
        with self.transaction():
            sizes = self._db.execute(
                f'DELETE FROM tasks WHERE entry IN ({selected}) RETURNING size',
                [*values, batch or -1],
            ).fetchall()
        self._ended_bytes -= sum(size for (size,) in sizes)
        return len(sizes)

    def close(self) -> None:
        self._db.close()
        if self._lock is not None:
            self._lock.close()
            self._lock = None


class _Transaction:
    """BEGIN ... COMMIT, or ROLLBACK on an exception (the connection is in autocommit mode)."""

    def __init__(self, db: sqlite3.Connection) -> None:
        self._db = db

    def __enter__(self) -> None:
        self._db.execute('BEGIN IMMEDIATE')

    def __exit__(self, kind: object, *_: object) -> None:
        if kind is None:
            self._db.execute('COMMIT')  # if it fails, the caller's error handling rolls back
        if self._db.in_transaction:  # an error, or a COMMIT that failed (disk full)
            with contextlib.suppress(sqlite3.Error):
                self._db.execute('ROLLBACK')
