"""Helpers of the gateways' tests (web, MQTT): a Task Manager with scripted servers, waits,
and the protocol's schema files."""

import json
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jsonschema
from std_srvs.srv import SetBool
from test_msgs.action import Fibonacci

from task_manager.protocol.__main__ import SCHEMA_FOLDER
from task_manager.testing.harness import RosHarness, WaitTimeoutError
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import NodeProcess, action_task, service_task, write_params_file
from task_manager.testing.servers import ScriptedActionServer, ScriptedService

TIMEOUT_SEC = 15.0
START_TIMEOUT_SEC = 20.0
SERVER_WAIT_TIMEOUT_SEC = 10.0


@dataclass
class Robot:
    """The node's process and the servers behind its tasks."""

    process: NodeProcess
    fib: ScriptedActionServer
    instant: ScriptedService


class ScriptedRobot:
    """A Task Manager (a real process) serving `fib` (a scripted Fibonacci action server in
    the test process, reentrant, cancelled by system/stop) and `instant` (a SetBool service
    that answers at once), with its history in `folder`. `start()` again after a stop."""

    def __init__(self, ros: RosHarness, folder: Path) -> None:
        prefix = f'/w{abs(hash(folder)) % 10**8}'
        self.fib = ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/fib')
        self.instant = ScriptedService(
            ros.node, SetBool, f'{prefix}/instant', on_call=lambda call: call.respond(success=True)
        )
        tasks = {
            'fib': action_task('fib', f'{prefix}/fib', reentrant=True, cancel_on_stop=True),
            'instant': service_task('instant', f'{prefix}/instant', reentrant=True),
        }
        self.params = write_params_file(
            folder / 'params.yaml',
            {
                'tasks': list(tasks),
                **tasks,
                'history_path': str(folder / 'history.sqlite'),
                # the node must discover this process's servers: 1 s (the default) is not
                # always enough with the other test process busy on the same 2 cores
                'server_wait_timeout': SERVER_WAIT_TIMEOUT_SEC,
                # serve at once: it is alone on the test run's domain
                'instance_check_timeout': 0,
            },
        )
        self.processes: list[NodeProcess] = []

    def start(self) -> Robot:
        process = NodeProcess(self.params)
        self.processes.append(process)
        process.wait_for_log(r'Task Manager ready', START_TIMEOUT_SEC)
        return Robot(process, self.fib, self.instant)

    def close(self) -> None:
        """Stop the nodes started, printing their output (pytest shows it when a test failed)."""
        for process in self.processes:
            process.stop()
            process.print_output()
        self.fib.destroy()
        self.instant.destroy()


class SharedBaseRobot:
    """A Task Manager (a real process) whose `drive` and `dock` both hold the resource `base`,
    each served by a scripted Fibonacci action server in the test process (`servers`), with a
    probe of the node (`probe`), so that one of them queues or pre-empts the other."""

    def __init__(self, ros: RosHarness, folder: Path) -> None:
        prefix = f'/b{abs(hash(folder)) % 10**8}'
        tasks = {
            name: action_task(name, f'{prefix}/{name}', resources=['base'])
            for name in ('drive', 'dock')
        }
        self.servers = {
            name: ScriptedActionServer(ros.node, Fibonacci, entry['topic'])
            for name, entry in tasks.items()
        }
        params = {
            'tasks': list(tasks),
            **tasks,
            'history_path': str(folder / 'history.sqlite'),
            'instance_check_timeout': 0,
        }
        self.process = NodeProcess(write_params_file(folder / 'params.yaml', params))
        self.process.wait_for_log(r'Task Manager ready', START_TIMEOUT_SEC)
        self.probe = TaskManagerProbe(ros)
        self.probe.wait_until_connected()

    def close(self) -> None:
        self.probe.destroy()
        self.process.stop()
        for server in self.servers.values():
            server.destroy()


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
