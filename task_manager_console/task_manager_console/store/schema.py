"""The fleet history's tables (SQLAlchemy Core), as the newest migration leaves them.

`migrations/` makes and upgrades them; a test checks that both agree.
"""

from sqlalchemy import (
    JSON,
    BigInteger,
    Column,
    DateTime,
    Index,
    Integer,
    MetaData,
    String,
    Table,
    UniqueConstraint,
)

from task_manager.core.bounds import TEXT_MAX_CHARACTERS

STATUS_MAX_CHARACTERS = 32
"""A task status (DONE, ERROR, CANCELED, ...)."""
ERROR_CODE_MAX_CHARACTERS = 64
"""An error code (invalid_request, timeout, ...)."""

metadata = MetaData(
    naming_convention={
        'ix': 'ix_%(table_name)s_%(column_0_N_name)s',
        'uq': 'uq_%(table_name)s_%(column_0_N_name)s',
        'pk': 'pk_%(table_name)s',
    }
)

RESULT_KEY = ('robot_id', 'sequence', 'task_id')
"""A result's exactly-once key: its robot, its sequence in the robot's history and its task."""

results = Table(
    'results',
    metadata,
    # SQLite's ROWID alias must be INTEGER; PostgreSQL gets a 64-bit key
    Column('id', BigInteger().with_variant(Integer, 'sqlite'), primary_key=True),
    Column('robot_id', String(TEXT_MAX_CHARACTERS), nullable=False),
    # the robot's history sequence: with robot_id and task_id, the exactly-once key
    Column('sequence', BigInteger, nullable=False),
    Column('task_id', String(TEXT_MAX_CHARACTERS), nullable=False),
    Column('task_name', String(TEXT_MAX_CHARACTERS), nullable=False),
    Column('source', String(TEXT_MAX_CHARACTERS), nullable=False),
    Column('status', String(STATUS_MAX_CHARACTERS), nullable=False),
    Column('error_code', String(ERROR_CODE_MAX_CHARACTERS), nullable=False),
    # stamps in UTC, without a zone (SQLite keeps none)
    Column('received', DateTime, nullable=True),
    Column('started', DateTime, nullable=True),
    # when it was stored, if the result has no end stamp
    Column('ended', DateTime, nullable=False),
    Column('result', JSON, nullable=True),
    # the mission it is a subtask of (its mission_id); empty if none
    Column('parent_id', String(TEXT_MAX_CHARACTERS), nullable=False),
    # what rows.py keeps of the rest of its Task document
    Column('details', JSON, nullable=False),
    Column('stored_at', DateTime, nullable=False),
    # the exactly-once key: a result delivered again is not stored again, and a robot whose
    # history began again (its sequence numbers from 1 again, other tasks) is stored
    UniqueConstraint(*RESULT_KEY),
)

# The history's queries (newest first: by ended, then id; by robot, task, name, status, source
# or time range); a filter's index ends with the whole order, so that its newest rows come
# first from it however they are spread.
HISTORY_INDEXES = (
    Index(None, results.c.ended, results.c.id),
    Index(None, results.c.robot_id, results.c.ended, results.c.id),
    Index(None, results.c.task_id),
    Index(None, results.c.task_name, results.c.ended, results.c.id),
    Index(None, results.c.status, results.c.ended, results.c.id),
    Index(None, results.c.source, results.c.ended, results.c.id),
)
