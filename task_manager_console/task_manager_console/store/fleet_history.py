"""`FleetHistory`: every result of every robot, stored exactly once, in a SQL database.

SQLite (a file, the default) or PostgreSQL (psycopg 3), behind SQLAlchemy Core. A result's key
is its robot's id, its `sequence` in that robot's own history and its task id: a result
delivered again (results come at least once) is not stored again (`INSERT ... ON CONFLICT DO
NOTHING`, on both databases), and a robot whose history began again (numbered from 1 again,
other tasks) is. The schema is versioned with Alembic: `open` creates it, or upgrades an older
database in place, before anything is stored.

Exceptions:
    DatabaseUnavailable -- the database cannot be reached or used (one line saying why)
"""

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Engine, create_engine, event, func, select
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.engine import URL, Connection, make_url
from sqlalchemy.exc import (
    ArgumentError,
    InterfaceError,
    NoSuchModuleError,
    OperationalError,
    SQLAlchemyError,
)

from task_manager.core.bounds import (
    FLEET_HISTORY_ROWS_DEFAULT,
    FLEET_HISTORY_ROWS_MAX,
    TEXT_MAX_CHARACTERS,
)
from task_manager.core.text.request_text import text_problem
from task_manager_console.store.rows import BadResultError, Document, document_of, row_of, utc
from task_manager_console.store.schema import RESULT_KEY as KEY
from task_manager_console.store.schema import results

LOG = logging.getLogger('task_manager_console.history')
MIGRATIONS = Path(__file__).with_name('migrations')
CONNECT_TIMEOUT_SEC = 5
"""How long opening a connection may take (PostgreSQL's connect_timeout)."""
SQLITE_BUSY_TIMEOUT_MS = 5000
"""How long a SQLite write waits for another's lock before it fails."""
FILTER_TEXTS = ('robot_id', 'task_id', 'task_name', 'status', 'source')


class _StoredBefore(Exception):  # noqa: N818 - a signal, not an error
    """Some rows of a batch were stored before: its transaction is rolled back."""


class DatabaseUnavailable(Exception):  # noqa: N818 - reads as a state, like TaskManagerUnavailable
    """The database cannot be reached or used; the message is one line saying why."""


@dataclass(frozen=True)
class HistoryFilter:
    """Which stored results a query returns, newest (by `ended`) first; empty text: any."""

    robot_id: str = ''
    task_id: str = ''
    task_name: str = ''
    status: str = ''
    source: str = ''
    ended_after: datetime | None = None
    """Ended at or after it (a naive time is UTC)."""
    ended_before: datetime | None = None
    """Ended before it (a naive time is UTC)."""
    limit: int = FLEET_HISTORY_ROWS_DEFAULT
    """At most this many, 1 to FLEET_HISTORY_ROWS_MAX."""

    def problem(self) -> str:
        """Why this filter cannot be asked (naming the field and the bound); empty if it can."""
        for field in FILTER_TEXTS:
            if problem := text_problem(field, getattr(self, field)):
                return problem
        if isinstance(self.limit, bool) or not 1 <= self.limit <= FLEET_HISTORY_ROWS_MAX:
            return f'limit must be from 1 to {FLEET_HISTORY_ROWS_MAX}, got {self.limit!r}'
        return ''


class FleetHistory:
    """The fleet history of one database; safe to use from several threads."""

    def __init__(self, engine: Engine) -> None:
        """Use `FleetHistory.open(url)`: it makes the engine and the schema."""
        self.engine = engine
        self.url = engine.url.render_as_string(hide_password=True)
        """The database's URL, without its password."""
        dialect = engine.dialect
        self._insert = postgresql.insert if dialect.name == 'postgresql' else sqlite.insert
        columns = [column for column in results.columns if column.name != 'id']
        # key: a column of a row, value: what makes its value the driver's (None: as it is)
        self._to_driver = [
            (column.name, column.type.dialect_impl(dialect).bind_processor(dialect))
            for column in columns
        ]
        mark = '?' if dialect.paramstyle == 'qmark' else '%s'
        self._insert_rows = (
            f'INSERT INTO results ({", ".join(column.name for column in columns)}) '
            f'VALUES ({", ".join([mark] * len(columns))}) '
            'ON CONFLICT (robot_id, sequence, task_id) DO NOTHING'
        )
        """The rows' INSERT in the driver's own terms (executemany, no statement to compile)."""

    @classmethod
    def open(cls, url: str) -> 'FleetHistory':
        """The fleet history at `url` (`sqlite:///path`, `postgresql://user@host/db`), created
        or upgraded to the newest schema; DatabaseUnavailable if it cannot be reached or used."""
        engine = _engine(url)
        try:
            with engine.begin() as connection:
                upgrade(connection)
        except SQLAlchemyError as error:
            engine.dispose()
            shown = engine.url.render_as_string(hide_password=True)
            message = f'cannot open the fleet history at {shown}: {_why(error)}'
            raise DatabaseUnavailable(message) from None
        return cls(engine)

    def close(self) -> None:
        self.engine.dispose()

    def store(self, robot_id: str, task: Document) -> bool:
        """Store `robot_id`'s result `task` (a Task document); True if it is new, False if it
        was stored before (the same robot, sequence and task). BadResultError if it cannot be a
        row."""
        return self.store_many([(robot_id, task)])[0]

    def store_many(self, items: Sequence[tuple[str, Document]]) -> list[bool]:
        """Store several results in one transaction (all or none); for each, whether it is new.
        BadResultError (of the first that cannot be a row) before anything is stored."""
        stored_at = utc(datetime.now(UTC))
        rows = [row_of(robot_id, task, stored_at) for robot_id, task in items]
        return self.store_rows(rows)

    def store_rows(self, rows: Sequence[Document]) -> list[bool]:
        """Store rows made by `rows.row_of`, in one transaction; for each, whether it is new
        (a key given twice in `rows` is new once, the first time). DatabaseUnavailable when
        the database cannot be reached (nothing stored), BadResultError when it refuses a value."""
        if not rows:
            return []
        try:
            if self._stored_all_new(rows):
                return [True] * len(rows)
        except (OperationalError, InterfaceError) as error:  # the database, not the rows
            raise DatabaseUnavailable(f'cannot store in {self.url}: {_why(error)}') from error
        except SQLAlchemyError:  # a value the database refuses: said below, row by row
            pass
        statement = (
            self._insert(results)
            .on_conflict_do_nothing(index_elements=list(KEY))
            .returning(*(results.c[name] for name in KEY))
        )
        try:
            with self.engine.begin() as connection:
                inserted = {tuple(r) for r in connection.execute(statement, rows)}
        except (OperationalError, InterfaceError) as error:  # the database, not the rows
            raise DatabaseUnavailable(f'cannot store in {self.url}: {_why(error)}') from error
        except SQLAlchemyError as error:  # what the rows hold (a value the database refuses)
            raise BadResultError(f'the database refused it: {_why(error)}') from error
        new: list[bool] = []
        for row in rows:
            key = tuple(row[name] for name in KEY)
            new.append(key in inserted)
            inserted.discard(key)
        return new

    def _stored_all_new(self, rows: Sequence[Document]) -> bool:
        """Store the rows if none was stored before (one executemany, the driver's fastest:
        a third of the time of the INSERT ... RETURNING of store_rows on PostgreSQL); False,
        and nothing stored, if one was (it inserted fewer rows than given)."""
        values = [
            tuple(row[name] if to_driver is None else to_driver(row[name])
                  for name, to_driver in self._to_driver)
            for row in rows
        ]  # fmt: skip
        try:
            with self.engine.begin() as connection:
                if connection.exec_driver_sql(self._insert_rows, values).rowcount != len(rows):
                    raise _StoredBefore
        except _StoredBefore:  # rolled back: RETURNING tells which are new
            return False
        return True

    def query(self, where: HistoryFilter) -> list[Document]:
        """The stored results `where` selects, newest first (Task documents with `robot_id`
        and `stored_at`). ValueError if the filter cannot be asked (see HistoryFilter.problem)."""
        if problem := where.problem():
            raise ValueError(problem)
        statement = select(results).order_by(results.c.ended.desc(), results.c.id.desc())
        for field in FILTER_TEXTS:
            if value := getattr(where, field):
                statement = statement.where(results.c[field] == value)
        if where.ended_after is not None:
            statement = statement.where(results.c.ended >= utc(where.ended_after))
        if where.ended_before is not None:
            statement = statement.where(results.c.ended < utc(where.ended_before))
        return self._documents(statement.limit(where.limit))

    def last_result(self, robot_id: str) -> Document | None:
        """The newest stored result of a robot (by `ended`), or None."""
        found = self.query(HistoryFilter(robot_id=robot_id, limit=1))
        return found[0] if found else None

    def count(self, robot_id: str = '') -> int:
        """How many results are stored (of one robot, if given)."""
        statement = select(func.count()).select_from(results)
        if robot_id:
            statement = statement.where(results.c.robot_id == robot_id)
        try:
            with self.engine.connect() as connection:
                return int(connection.execute(statement).scalar_one())
        except SQLAlchemyError as error:
            raise DatabaseUnavailable(f'cannot read {self.url}: {_why(error)}') from error

    def revision(self) -> str | None:
        """The schema's Alembic revision in the database."""
        with self.engine.connect() as connection:
            return MigrationContext.configure(connection).get_current_revision()

    def _documents(self, statement: Any) -> list[Document]:
        try:
            with self.engine.connect() as connection:
                return [document_of(row) for row in connection.execute(statement).mappings()]
        except SQLAlchemyError as error:
            raise DatabaseUnavailable(f'cannot read {self.url}: {_why(error)}') from error


def head_revision() -> str:
    """The newest revision of the schema this code knows."""
    head = ScriptDirectory.from_config(_alembic_config()).get_current_head()
    assert head is not None
    return head


def upgrade(connection: Connection, revision: str = 'head') -> None:
    """Create the schema, or upgrade it in place, to `revision` (Alembic's migrations)."""
    config = _alembic_config()
    config.attributes['connection'] = connection
    command.upgrade(config, revision)


def _alembic_config() -> Config:
    config = Config()
    config.set_main_option('script_location', str(MIGRATIONS))
    return config


def database_url(url: str) -> URL:
    """SQLAlchemy's URL of `url`: PostgreSQL through psycopg 3 (postgresql:// or
    postgres://); DatabaseUnavailable if it names no database SQLAlchemy can reach."""
    try:
        parsed = make_url(url)
    except ArgumentError:
        raise DatabaseUnavailable(
            f'{url[:TEXT_MAX_CHARACTERS]!r} is no database URL; expected sqlite:///path or '
            'postgresql://user@host[:port]/database'
        ) from None
    if parsed.drivername in ('postgresql', 'postgres'):
        parsed = parsed.set(drivername='postgresql+psycopg')
    if parsed.get_backend_name() not in ('sqlite', 'postgresql'):
        raise DatabaseUnavailable(
            f'{parsed.render_as_string(hide_password=True)}: the fleet history is on SQLite '
            '(sqlite:///path) or PostgreSQL (postgresql://...)'
        )
    return parsed


def _engine(url: str) -> Engine:
    parsed = database_url(url)
    shown = parsed.render_as_string(hide_password=True)
    try:
        if parsed.get_backend_name() == 'sqlite':
            if parsed.database and parsed.database != ':memory:':
                Path(parsed.database).parent.mkdir(parents=True, exist_ok=True)
            engine = create_engine(parsed, connect_args={'timeout': SQLITE_BUSY_TIMEOUT_MS / 1000})
            event.listen(engine, 'connect', _sqlite_settings)
            return engine
        return create_engine(
            parsed, pool_pre_ping=True, connect_args={'connect_timeout': CONNECT_TIMEOUT_SEC}
        )
    except (NoSuchModuleError, OSError) as error:
        raise DatabaseUnavailable(f'cannot open the fleet history at {shown}: {error}') from None


def _sqlite_settings(connection: Any, _: Any) -> None:
    """WAL (readers never wait for the writer) and a synced commit: a result acknowledged to
    the broker is on disk."""
    cursor = connection.cursor()
    cursor.execute('PRAGMA journal_mode=WAL')
    cursor.execute('PRAGMA synchronous=FULL')
    cursor.close()


def _why(error: SQLAlchemyError) -> str:
    """The first line of the database's own message."""
    cause = getattr(error, 'orig', None) or error
    lines = [line.strip() for line in str(cause).splitlines() if line.strip()]
    return lines[0] if lines else type(cause).__name__
