"""Tools of the console's tests and benchmarks: a real PostgreSQL server, and the results a Fleet
stores, to wait on (the simulated robots are in simulated_robots.py)."""

import re
import shutil
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from task_manager.testing.output_reader import OutputReader
from task_manager_console.fleet import Change, Fleet
from task_manager_console.simulation.robot_loop import TIMEOUT_SEC
from task_manager_console.store.local_postgres import (
    READY_LINE,
    START_TIMEOUT_SEC,
    PostgresError,
    PostgresServer,
)

STOP_TIMEOUT_SEC = 30.0
CONSOLE_USER = 'console'
"""The console's account on the tests' broker."""
ROBOTS = ('robot1', 'robot2', 'robot3')
Document = dict[str, Any]


@contextmanager
def postgres_server() -> Iterator[PostgresServer]:
    """A PostgreSQL server in a new temporary folder (under /tmp, where the `postgres` user
    reaches it when root starts it), stopped and removed at the end. It runs as a child of this
    process (`PostgresServer.command`), which it does not outlive: a test process ended by its
    watchdog (conftest.py), whose teardown never runs, left pg_ctl's server running."""
    folder = Path(tempfile.mkdtemp(prefix='fleet-postgres-'))
    server = PostgresServer(folder)
    try:
        server.make_cluster()
        process = subprocess.Popen(
            server.command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
        )
        assert process.stderr is not None
        log = OutputReader(process.stderr)
        try:
            if log.find(re.escape(READY_LINE), START_TIMEOUT_SEC) is None:
                raise PostgresError(
                    f'the test server did not start within {START_TIMEOUT_SEC} s: '
                    + ' / '.join(log.lines[-5:])
                )
            yield server
        finally:
            try:
                server.stop()  # this one, or one a test started again with `start()`
            finally:
                try:
                    process.wait(STOP_TIMEOUT_SEC)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait()
    finally:
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
