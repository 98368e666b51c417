"""`Ingest`: the results the console receives, stored in the fleet history in batches (one
transaction each, in the order they came) on a thread of its own, each acknowledged to the
broker only once it is stored (or refused for good).

While the database is away a batch is tried again, after 0.5 s, doubling up to 5 s, and none of
it is acknowledged: the broker keeps those results, and the rest wait with it (the console's
MQTT Receive Maximum bounds what it holds). A result that can never be a row (BadResultError) is
reported and acknowledged; a batch the database refuses is stored row by row to find the row it
refuses. A result received twice is stored once (its robot, sequence and task id are its key).
"""

import logging
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime

from task_manager_console.store.fleet_history import DatabaseUnavailable, FleetHistory
from task_manager_console.store.rows import BadResultError, Document, row_of, utc

LOG = logging.getLogger('task_manager_console.fleet')
STORE_BATCH_MAX = 500
"""Results stored in one transaction, at most."""
BATCH_GATHER_SEC = 0.05
"""How long a batch waits for more results after its first (then it is stored as it is): a
transaction, its commit (synced to disk) and its acknowledgements cost as much for one result
as for many."""
RETRY_MIN_SEC = 0.5
RETRY_MAX_SEC = 5.0
"""While the database is away, a store is tried again after 0.5 s, doubling up to 5 s."""


@dataclass(frozen=True)
class Held:
    """A result received and not yet acknowledged to the broker."""

    robot_id: str
    task: Document
    acknowledge: Callable[[], None]


class Ingest:
    """Stores what `put` hands it, on its thread (`start`, then `stop`)."""

    def __init__(
        self,
        history: FleetHistory,
        *,
        on_stored: Callable[[list[Document]], None],
        on_bad: Callable[[str, str], None],
        on_database: Callable[[bool], None],
    ) -> None:
        """Called on its thread: `on_stored(rows)` with the rows newly stored by a batch (before
        it is acknowledged), `on_bad(robot_id, why)` for a result that can never be stored,
        `on_database(up)` when the database goes away and when it is back."""
        self.history = history
        self.duplicates = 0
        """Results received again and not stored again."""
        self.database_up = True
        """False while stores fail (results wait with the broker meanwhile)."""
        self._on_stored = on_stored
        self._on_bad = on_bad
        self._on_database = on_database
        self._held: queue.Queue[Held | None] = queue.Queue()
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name='fleet-history')

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        """Finish (and acknowledge) the batch being stored, then end: what is still held is
        never acknowledged, so the broker delivers it again at the next connection."""
        self._stopping.set()
        self._held.put(None)
        if self._thread.is_alive():
            self._thread.join()

    def put(self, robot_id: str, task: Document, acknowledge: Callable[[], None]) -> None:
        """Store a result received (from any thread, never waiting)."""
        self._held.put(Held(robot_id, task, acknowledge))

    def waiting(self) -> int:
        """Results received and not yet stored (nor acknowledged)."""
        return self._held.qsize()

    def _run(self) -> None:
        """Batches of results, in the order they came, until stopped."""
        while True:
            first = self._held.get()
            if first is None or self._stopping.is_set():
                return
            batch = [first]
            if self._held.qsize() < STORE_BATCH_MAX:  # more to come: let them (one wake-up)
                self._stopping.wait(BATCH_GATHER_SEC)
            while len(batch) < STORE_BATCH_MAX:
                try:
                    item = self._held.get_nowait()
                except queue.Empty:
                    break
                if item is None:
                    self._held.put(None)  # the end, once this batch is stored
                    break
                batch.append(item)
            try:
                self._store_batch(batch)
            except Exception:  # a bug of ours: logged, the thread goes on (not acknowledged)
                LOG.exception('storing %d results failed', len(batch))

    def _store_batch(self, batch: list[Held]) -> None:
        """Store a batch (retrying while the database is away), then acknowledge it all."""
        stored_at = utc(datetime.now(UTC))
        rows: list[Document] = []
        for held in batch:
            try:
                rows.append(row_of(held.robot_id, held.task, stored_at))
            except BadResultError as error:  # never storable: acknowledged, counted
                self._on_bad(held.robot_id, str(error))
        new = self._stored(rows)
        if new is None:  # stopping: the broker keeps them
            return
        self.duplicates += new.count(False)
        self._on_stored([row for row, is_new in zip(rows, new, strict=True) if is_new])
        for held in batch:
            held.acknowledge()

    def _stored(self, rows: list[Document]) -> list[bool] | None:
        """Whether each row is new, once stored; None if stopped first."""
        delay = RETRY_MIN_SEC
        while not self._stopping.is_set():
            try:
                new = self._store_rows(rows)
            except DatabaseUnavailable as error:
                if self.database_up:
                    self._set_database_up(False)
                    LOG.error(
                        '%s; the results wait with the broker (not acknowledged), '
                        'trying again every %.0f s at most',
                        error,
                        RETRY_MAX_SEC,
                    )
                self._stopping.wait(delay)
                delay = min(delay * 2, RETRY_MAX_SEC)
                continue
            if not self.database_up:
                self._set_database_up(True)
                LOG.info('the fleet history at %s is back: storing again', self.history.url)
            return new
        return None

    def _set_database_up(self, up: bool) -> None:
        self.database_up = up
        self._on_database(up)

    def _store_rows(self, rows: list[Document]) -> list[bool]:
        """history.store_rows; a batch the database refuses is stored row by row, and a row
        it refuses alone is reported as bad (never stored)."""
        try:
            return self.history.store_rows(rows)
        except BadResultError as error:
            if len(rows) == 1:
                self._on_bad(rows[0]['robot_id'], str(error))
                return [False]
        return [new for row in rows for new in self._store_rows([row])]
