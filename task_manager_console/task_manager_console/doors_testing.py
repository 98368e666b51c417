"""Tools of the tests of the console's doors: `task-manager-console` run as users run it, its
HTTP clients by role (the web gateway's tests' tokens, task_manager_web.doors_testing), and its
event stream read as it comes (no rclpy here, as in the rest of the console)."""

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
from task_manager_mqtt.broker import MosquittoBroker
from task_manager_web.doors_testing import ADMIN, TOKEN_FILE, TOKENS, VIEWER, client_of
from task_manager_web.doors_testing import OPERATOR as OPERATOR

from task_manager.testing.output_reader import OutputReader
from task_manager_console.main import READY_LINE
from task_manager_console.simulation.robot_loop import TIMEOUT_SEC
from task_manager_console.testing import CONSOLE_USER

CONSOLE = str(Path(sys.executable).with_name('task-manager-console'))
DASHBOARD_LINE = r'dashboard: (?P<url>http://[^/\s]+)/'
Document = dict[str, Any]


class ConsoleProcess:
    """`task-manager-console` on a broker (the `console` account, its password in a file) and
    a database, its doors on a free port with TOKEN_FILE's tokens; `url` once it listens."""

    def __init__(
        self, broker: MosquittoBroker, database_url: str, folder: Path, *args: str
    ) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        password_file = folder / 'console_password'
        password_file.write_text(broker.passwords[CONSOLE_USER])
        password_file.chmod(0o600)
        token_file = folder / 'tokens'
        token_file.write_text(TOKEN_FILE)
        token_file.chmod(0o600)
        command = [
            CONSOLE,
            '--broker-url', f'mqtt://{CONSOLE_USER}@127.0.0.1:{broker.port}',
            '--password-file', str(password_file),
            '--database', database_url,
            '--port', '0',
            '--token-file', str(token_file),
            *args,
        ]  # fmt: skip
        self.process = subprocess.Popen(
            command,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=dict(os.environ, PYTHONUNBUFFERED='1'),
        )
        assert self.process.stdout is not None
        self._output = OutputReader(self.process.stdout)
        self.lines = self._output.lines
        try:
            self.wait_for_line(READY_LINE)
            match = re.search(DASHBOARD_LINE, self.wait_for_line(DASHBOARD_LINE))
        except AssertionError:
            self.stop()
            raise
        assert match is not None
        self.url = match['url']

    def wait_for_line(self, pattern: str, timeout_sec: float = TIMEOUT_SEC) -> str:
        """Wait for an output line matching the regular expression `pattern`; the line."""
        line = self._output.find(pattern, timeout_sec)
        if line is None:
            output = '\n'.join(self.lines)
            raise AssertionError(f'no line matching {pattern!r}; output:\n{output}')
        return line

    def stop(self, timeout_sec: float = TIMEOUT_SEC) -> int:
        """SIGINT (a clean stop), then its exit code; killed if it does not stop in time."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        try:
            code = self.process.wait(timeout_sec)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            raise
        self._output.join(timeout_sec)
        return code

    def client(self, role: str | None = ADMIN) -> httpx.Client:
        """An HTTP client with the token of `role` (None: no token)."""
        return client_of(self.url, role, TIMEOUT_SEC)


def wait_for(read: Callable[[], Any], condition: Callable[[Any], Any], what: str) -> Any:
    """Read until `condition(read())` holds (an HTTP read of another process, which has no
    event to wait on but its stream), every 20 ms for at most TIMEOUT_SEC; the last read."""
    deadline = time.monotonic() + TIMEOUT_SEC
    while not condition(value := read()):
        if time.monotonic() > deadline:
            raise AssertionError(f'{what}: not within {TIMEOUT_SEC} s; last: {value!r}')
        time.sleep(0.02)
    return value


class EventReader:
    """The console's event stream (GET /api/events), read in a thread: every event, to wait on."""

    def __init__(self, console: ConsoleProcess, role: str = VIEWER) -> None:
        self.events: list[tuple[str, Document]] = []
        self._changed = threading.Condition()
        self._client = httpx.Client(base_url=console.url, timeout=httpx.Timeout(TIMEOUT_SEC))
        self._response = self._client.send(
            self._client.build_request('GET', '/api/events', params={'token': TOKENS[role]}),
            stream=True,
        )
        assert self._response.status_code == 200, self._response.read()
        self.headers = self._response.headers
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        kind = ''
        try:
            for line in self._response.iter_lines():
                if line.startswith('event: '):
                    kind = line.removeprefix('event: ')
                elif line.startswith('data: '):
                    with self._changed:
                        self.events.append((kind, json.loads(line.removeprefix('data: '))))
                        self._changed.notify_all()
        except httpx.HTTPError:  # closed by the test
            return

    def wait(self, condition: Callable[[list[tuple[str, Document]]], Any], what: str) -> Any:
        """Wait until `condition(events)` is true; its value."""
        with self._changed:
            value = self._changed.wait_for(lambda: condition(self.events), TIMEOUT_SEC)
        if not value:
            raise AssertionError(f'{what}: not within {TIMEOUT_SEC} s; events: {self.events!r}')
        return value

    def close(self) -> None:
        self._response.close()
        self._client.close()
