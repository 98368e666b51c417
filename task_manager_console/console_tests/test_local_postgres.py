"""The tests' PostgreSQL server does not outlive the process that started it, however that
process ends (a test process ended by its watchdog runs no teardown)."""

import shutil
import subprocess
import sys
from pathlib import Path

import psutil

from task_manager_console.testing import wait_until

START_SEC = 60.0
END_SEC = 30.0
STARTER = """
import sys
from task_manager_console.testing import postgres_server
with postgres_server() as server:
    print(server.folder, flush=True)
    sys.stdin.readline()
"""


def _running(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def test_the_server_ends_with_the_process_that_started_it_killed() -> None:
    starter = subprocess.Popen(
        [sys.executable, '-c', STARTER], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    assert starter.stdout is not None
    folder = Path(starter.stdout.readline().strip())
    try:
        assert folder.name.startswith('fleet-postgres-'), folder
        server = int((folder / 'data' / 'postmaster.pid').read_text().split()[0])
        assert _running(server)

        starter.kill()
        starter.wait(START_SEC)

        wait_until(lambda: not _running(server), END_SEC, 'the server ended with its starter')
    finally:
        if starter.poll() is None:
            starter.kill()
            starter.wait()
        shutil.rmtree(folder, ignore_errors=True)
