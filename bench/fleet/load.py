"""The load of the console benchmark: robots that run one task after another at a given rate
(each task three messages, as its bridge sends them), and a fleet history filled in bulk."""

import json
import math
import random
import threading
import time
from collections.abc import Sequence
from datetime import UTC, datetime, timedelta

from sqlalchemy import func, select
from task_manager_console.simulation.robot import EVENTS_PER_TASK, SimulatedRobot
from task_manager_console.store.fleet_history import FleetHistory
from task_manager_console.store.schema import HISTORY_INDEXES, results

from bench.harness.replies import BenchError

TICK_SEC = 0.005
"""How often the paced robots send what is due."""
EVENTS_PER_TICK_MAX = 1000
"""Sent in one go at most: between two, the robots' loop reads and writes (acknowledgements,
keep-alives); a robot the broker hears nothing from for 1.5 keep-alives is disconnected."""
FILL_BATCH = 10_000
"""Rows of one INSERT of the bulk fill."""
FILL_DAYS = 30
"""The bulk fill's results ended over the last 30 days."""
STATUSES = (('DONE', 90), ('ERROR', 8), ('CANCELED', 2))
"""Statuses of the bulk fill's results, and how many in 100."""
SOURCES = ('CLOUD', 'CLOUD:alice', 'WEB:bob', 'schedule:nightly')
FILL_SEQUENCE_BASE = 10**12
"""The bulk fill's sequences start above any a simulated robot reaches."""


class PacedLoad:
    """`robots` sending their next message in turn, `rate_per_sec` messages a second in all,
    until each has sent `tasks_per_robot` tasks (so each robot's last message is a result)."""

    def __init__(
        self, robots: Sequence[SimulatedRobot], rate_per_sec: float, tasks_per_robot: int
    ) -> None:
        self.robots = list(robots)
        self.rate_per_sec = rate_per_sec
        self.events = len(self.robots) * EVENTS_PER_TASK * tasks_per_robot
        self.results = len(self.robots) * tasks_per_robot
        self.sent = 0
        self.started_at = 0.0
        """time.monotonic() of the start."""
        self.last_sent_at = 0.0
        self._done = threading.Event()

    @classmethod
    def lasting(
        cls, robots: Sequence[SimulatedRobot], rate_per_sec: float, duration_sec: float
    ) -> 'PacedLoad':
        """A load of about `duration_sec` at `rate_per_sec` (whole tasks of every robot)."""
        tasks = math.ceil(rate_per_sec * duration_sec / (len(robots) * EVENTS_PER_TASK))
        return cls(robots, rate_per_sec, tasks)

    def run(self, timeout_sec: float) -> None:
        """Send it all (on the robots' loop), and wait until it is sent."""
        self.started_at = time.monotonic()
        self.robots[0].loop.every(TICK_SEC, self._tick)
        if not self._done.wait(timeout_sec):
            raise BenchError(f'paced load: {self.sent} of {self.events} sent in {timeout_sec} s')

    @property
    def offered_per_sec(self) -> float:
        """The rate at which it was sent (below `rate_per_sec` if the sender fell behind)."""
        return self.events / max(self.last_sent_at - self.started_at, 1e-9)

    def _tick(self) -> bool:
        now = time.monotonic()
        due = self.events
        if math.isfinite(self.rate_per_sec):
            due = min(int((now - self.started_at) * self.rate_per_sec), due)
        due = min(due, self.sent + EVENTS_PER_TICK_MAX)
        count = len(self.robots)
        while self.sent < due:
            self.robots[self.sent % count].next_event()
            self.sent += 1
        if self.sent < self.events:
            return True
        self.last_sent_at = time.monotonic()
        self._done.set()
        return False


def last_id(history: FleetHistory) -> int:
    """The newest row's id (0: none)."""
    with history.engine.connect() as connection:
        return int(connection.execute(select(func.max(results.c.id))).scalar() or 0)


def rows_after(history: FleetHistory, after_id: int) -> int:
    """How many rows have an id above `after_id`."""
    statement = select(func.count()).select_from(results).where(results.c.id > after_id)
    with history.engine.connect() as connection:
        return int(connection.execute(statement).scalar_one())


def lags_sec(history: FleetHistory, after_id: int) -> list[float]:
    """Of each row above `after_id`: seconds from its result's end (stamped by the robot as it
    sent it) to its `stored_at` (stamped by the console as its transaction began)."""
    statement = select(results.c.ended, results.c.stored_at).where(results.c.id > after_id)
    with history.engine.connect() as connection:
        return [(stored - ended).total_seconds() for ended, stored in connection.execute(statement)]


def stored_span_sec(history: FleetHistory, after_id: int) -> float:
    """Seconds from the first row above `after_id` stored to the last (their stored_at)."""
    statement = select(func.min(results.c.stored_at), func.max(results.c.stored_at))
    with history.engine.connect() as connection:
        first, last = connection.execute(statement.where(results.c.id > after_id)).one()
    span: timedelta = last - first
    return max(span.total_seconds(), 1e-3)


def wait_rows(history: FleetHistory, after_id: int, count: int, timeout_sec: float) -> float:
    """Wait until `count` rows are stored above `after_id` (read every 50 ms: another process
    writes them); time.monotonic() when seen."""
    deadline = time.monotonic() + timeout_sec
    while (stored := rows_after(history, after_id)) < count:
        if time.monotonic() > deadline:
            raise BenchError(f'{stored} of {count} results stored within {timeout_sec} s')
        time.sleep(0.05)
    return time.monotonic()


def fill(
    history: FleetHistory, robot_ids: Sequence[str], total: int, task_names: Sequence[str]
) -> float:
    """Insert rows until the table holds `total` (results of these robots ended over the last
    FILL_DAYS), in bulk through the driver (PostgreSQL's COPY, SQLite's executemany), not
    through the console, the history's indexes made again after it; then ANALYZE, as after any
    bulk load. The seconds it took."""
    started = time.perf_counter()
    missing = total - rows_after(history, 0)
    postgres = history.engine.dialect.name == 'postgresql'
    with history.engine.begin() as connection:
        for index in HISTORY_INDEXES:  # made again once the rows are in: much faster
            index.drop(connection)
        cursor = connection.connection.driver_connection.cursor()  # type: ignore[union-attr]
        for first in range(0, missing, FILL_BATCH):
            rows = _fill_rows(first, min(first + FILL_BATCH, missing), missing, robot_ids,
                              task_names, postgres)  # fmt: skip
            if postgres:
                with cursor.copy(f'COPY results ({", ".join(FILL_COLUMNS)}) FROM STDIN') as copy:
                    for row in rows:
                        copy.write_row(row)
            else:
                marks = ', '.join('?' * len(FILL_COLUMNS))
                cursor.executemany(
                    f'INSERT INTO results ({", ".join(FILL_COLUMNS)}) VALUES ({marks})', rows
                )
        for index in HISTORY_INDEXES:
            index.create(connection)
        cursor.execute('ANALYZE results' if postgres else 'ANALYZE')
    return time.perf_counter() - started


FILL_COLUMNS = (
    'robot_id', 'sequence', 'task_id', 'task_name', 'source', 'status', 'error_code',
    'received', 'started', 'ended', 'result', 'parent_id', 'details', 'stored_at',
)  # fmt: skip
RESULT_JSON = json.dumps({'sequence': [0, 1, 1, 2]})
DETAILS_JSON = json.dumps({'duration_sec': 58.0, 'priority': 0, 'attempt': 1, 'decisions': []})


def _fill_rows(
    first: int,
    end: int,
    count: int,
    robot_ids: Sequence[str],
    task_names: Sequence[str],
    postgres: bool,
) -> list[tuple[object, ...]]:
    """Rows `first` to `end` of `count`, the newest first: statuses and sources drawn at random
    (seeded), stamps as the database keeps them (SQLite: text as SQLAlchemy writes it)."""
    chooser = random.Random(first)
    statuses = [status for status, weight in STATUSES for _ in range(weight)]
    now = datetime.now(UTC).replace(tzinfo=None)
    span_sec = FILL_DAYS * 24 * 3600
    stamp = (lambda moment: moment) if postgres else _sqlite_stamp
    rows: list[tuple[object, ...]] = []
    for number in range(first, end):
        ended = now - timedelta(seconds=span_sec * number / count)
        status = chooser.choice(statuses)
        rows.append((
            robot_ids[number % len(robot_ids)], FILL_SEQUENCE_BASE + number, f'fill-{number}',
            chooser.choice(task_names), chooser.choice(SOURCES), status,
            'timeout' if status == 'ERROR' else '', stamp(ended - timedelta(seconds=60)),
            stamp(ended - timedelta(seconds=58)), stamp(ended), RESULT_JSON, '', DETAILS_JSON,
            stamp(ended),
        ))  # fmt: skip
    return rows


def _sqlite_stamp(moment: datetime) -> str:
    """A time as SQLAlchemy keeps it in SQLite (its DATETIME's storage format)."""
    return moment.strftime('%Y-%m-%d %H:%M:%S.%f')
