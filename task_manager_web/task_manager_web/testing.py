"""Helpers of the gateway's tests and benchmarks: the gateway run as users do, waits, schemas."""

import json
import re
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jsonschema

from task_manager.protocol.__main__ import SCHEMA_FOLDER
from task_manager.testing.harness import WaitTimeoutError
from task_manager.testing.process import NodeProcess
from task_manager.testing.servers import ScriptedActionServer, ScriptedService

GATEWAY_EXECUTABLE = str(Path(sys.executable).with_name('task-manager-web'))
DASHBOARD_LINE = r'dashboard: (?P<url>http://\S+)/\?token=(?P<token>\S+)'
START_TIMEOUT_SEC = 20.0


class GatewayProcess(NodeProcess):
    """`task-manager-web --port 0 --token-file F [args]`; its URL and token once it listens."""

    def __init__(self, token_file: Path, *args: str) -> None:
        super().__init__(
            None,
            command=[GATEWAY_EXECUTABLE, '--port', '0', '--token-file', str(token_file), *args],
        )
        match = re.search(DASHBOARD_LINE, self.wait_for_log(DASHBOARD_LINE, START_TIMEOUT_SEC))
        assert match is not None
        self.url = match['url']
        self.token = match['token']


TIMEOUT_SEC = 15.0


@dataclass
class Robot:
    """The node's process and the servers behind its tasks."""

    process: NodeProcess
    fib: ScriptedActionServer
    instant: ScriptedService


def wait_until(condition: Callable[[], Any], what: str, timeout_sec: float = TIMEOUT_SEC) -> Any:
    """Check `condition` until it is true (each 20 ms, at most `timeout_sec`); its value."""
    deadline = time.monotonic() + timeout_sec
    while not (value := condition()):
        if time.monotonic() > deadline:
            raise WaitTimeoutError(f'{what}: not within {timeout_sec} s')
        threading.Event().wait(0.02)
    return value


def check(document: Any, schema_name: str) -> Any:
    """`document` is valid against the protocol's schema file `schema_name`; returns it."""
    schema = json.loads((SCHEMA_FOLDER / f'{schema_name}.schema.json').read_text())
    validator = jsonschema.Draft202012Validator(schema, format_checker=jsonschema.FormatChecker())
    validator.validate(document)
    return document
