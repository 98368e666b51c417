"""Tools of the console's tests and benchmarks: a real PostgreSQL server, and the results a Fleet
stores, to wait on (the simulated robots are in simulated_robots.py)."""

import shutil
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from task_manager_console.fleet import Change, Fleet
from task_manager_console.simulation.robot_loop import TIMEOUT_SEC
from task_manager_console.store.local_postgres import PostgresServer

CONSOLE_USER = 'console'
"""The console's account on the tests' broker."""
ROBOTS = ('robot1', 'robot2', 'robot3')
Document = dict[str, Any]


@contextmanager
def postgres_server() -> Iterator[PostgresServer]:
    """A PostgreSQL server in a new temporary folder (under /tmp, where the `postgres` user
    reaches it when root starts it), stopped and removed at the end."""
    folder = Path(tempfile.mkdtemp(prefix='fleet-postgres-'))
    server = PostgresServer(folder)
    try:
        server.start()
        yield server
    finally:
        server.stop()
        shutil.rmtree(folder, ignore_errors=True)


class Results:
    """The results a Fleet stores, as it stores them (its `on_change`), to wait on."""

    def __init__(self, fleet: Fleet) -> None:
        self.stored: list[dict[str, Any]] = []
        self._changed = threading.Condition()
        fleet.on_change(self._on_change)

    def _on_change(self, change: Change) -> None:
        if change.result is not None:
            with self._changed:
                self.stored.append(change.result)
                self._changed.notify_all()

    def wait(self, count: int, timeout_sec: float = TIMEOUT_SEC) -> list[dict[str, Any]]:
        """Wait until `count` results are stored; them."""
        with self._changed:
            if not self._changed.wait_for(lambda: len(self.stored) >= count, timeout_sec):
                raise AssertionError(f'{len(self.stored)} results stored, not {count}')
            return list(self.stored)


def wait_until(condition: Callable[[], object], timeout_sec: float, what: str) -> None:
    """Check `condition` until it holds (every 50 ms: what it reads, a database another
    process writes, has no events to wait on); AssertionError naming `what` if it does not
    within `timeout_sec`."""
    deadline = time.monotonic() + timeout_sec
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f'{what}: not within {timeout_sec} s')
        time.sleep(0.05)
