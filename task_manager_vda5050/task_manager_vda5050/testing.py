"""Helpers of the adapter's tests: the broker, the adapter and the demo robot run as users
run them, and the independent master control (test_tools/master.js, npm's vda-5050-lib)."""

import itertools
import json
import shutil
import subprocess
import sys
import threading
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

from task_manager_mqtt.broker import READY_LINE

from task_manager.client import TaskManagerClient, TaskState
from task_manager.testing.gateway import wait_until
from task_manager.testing.harness import WaitTimeoutError
from task_manager.testing.process import TEST_NICENESS, NodeProcess, nice_option
from task_manager_vda5050.broker import VdaBroker
from task_manager_vda5050.mapping import DEMO_MAPPING
from task_manager_vda5050.topics import timestamp

ADAPTER_EXECUTABLE = str(Path(sys.executable).with_name('task-manager-vda5050'))
PACKAGE = Path(__file__).resolve().parents[1]
TEST_TOOLS = PACKAGE / 'test_tools'
MASTER_SCRIPT = TEST_TOOLS / 'master.js'
CONNECTED_LINE = r'connected to the broker'
START_TIMEOUT_SEC = 30.0
TIMEOUT_SEC = 20.0
MANUFACTURER = 'acme'
SERIAL = 'robot1'
TESTER = 'tester'
"""A second master account: the raw messages the library would never send."""


class BrokerProcess(VdaBroker):
    process: NodeProcess | None = None

    def start(self) -> None:
        self.process = NodeProcess(None, command=self.command)
        self.process.wait_for_log(READY_LINE, START_TIMEOUT_SEC)

    def stop(self) -> int:
        if self.process is None:
            return 0
        process, self.process = self.process, None
        return process.stop()


class AdapterProcess(NodeProcess):
    """`task-manager-vda5050` for SERIAL of MANUFACTURER with the demo's mapping (or
    `mapping`); `nice`: None for the adapter's default."""

    def __init__(
        self,
        broker: VdaBroker,
        *args: str,
        wait: bool = True,
        mapping: Path = DEMO_MAPPING,
        nice: int | None = TEST_NICENESS,
    ) -> None:
        password_file = broker.folder / f'{SERIAL}.password'
        password_file.write_text(broker.passwords[SERIAL])
        command = [
            ADAPTER_EXECUTABLE,
            '--manufacturer',
            MANUFACTURER,
            '--serial-number',
            SERIAL,
            '--broker-url',
            f'mqtt://{SERIAL}@127.0.0.1:{broker.port}',
            '--password-file',
            str(password_file),
            '--mapping',
            str(mapping),
            *nice_option(nice),
            *args,
        ]
        super().__init__(None, command=command)
        if wait:
            try:
                self.wait_for_log(CONNECTED_LINE, START_TIMEOUT_SEC)
            except WaitTimeoutError:
                if self.process.poll() is None:  # not left running: its stacks say where
                    self.abort(f'did not connect within {START_TIMEOUT_SEC:g} s')
                raise


def node_executable() -> str:
    return shutil.which('node') or 'node'


class Master:
    """The independent master control, one process; `events` holds what it printed."""

    def __init__(self, broker: VdaBroker, master_user: str) -> None:
        if not (TEST_TOOLS / 'node_modules' / 'vda-5050-lib').is_dir():
            raise RuntimeError(f'vda-5050-lib is not installed: run `make install` ({TEST_TOOLS})')
        self.events: list[dict[str, Any]] = []
        self._changed = threading.Condition()
        self._ids = itertools.count(1)
        self.process = subprocess.Popen(
            [node_executable(), str(MASTER_SCRIPT)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            cwd=TEST_TOOLS,
        )
        threading.Thread(target=self._read, daemon=True).start()
        self.wait_for(lambda e: e['event'] == 'ready', 'the master started')
        self.command(
            'start',
            brokerUrl=f'mqtt://127.0.0.1:{broker.port}',
            username=master_user,
            password=broker.passwords[master_user],
            rawUsername=TESTER,
            rawPassword=broker.passwords[TESTER],
            interfaceName=broker.interface_name,
            manufacturer=MANUFACTURER,
            serialNumber=SERIAL,
        )

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            try:
                event = json.loads(line)
            except json.JSONDecodeError:
                event = {'event': 'output', 'text': line.rstrip()}
            with self._changed:
                self.events.append(event)
                self._changed.notify_all()

    def command(self, cmd: str, **fields: Any) -> dict[str, Any]:
        """Send a command, wait for its answer ('done'); RuntimeError if it failed."""
        command_id = next(self._ids)
        assert self.process.stdin is not None
        self.process.stdin.write(json.dumps({'cmd': cmd, 'id': command_id, **fields}) + '\n')
        self.process.stdin.flush()
        answer = self.wait_for(
            lambda e: e.get('id') == command_id and e['event'] in ('done', 'failed'), cmd
        )
        if answer['event'] == 'failed':
            raise RuntimeError(f'master: {cmd} failed: {answer["error"]}')
        return answer

    def wait_for(
        self,
        condition: Callable[[dict[str, Any]], Any],
        what: str,
        timeout_sec: float = TIMEOUT_SEC,
    ) -> dict[str, Any]:
        """The first event (of all so far) for which `condition` holds, waiting for it."""
        with self._changed:
            found = self._changed.wait_for(
                lambda: next((e for e in self.events if condition(e)), None), timeout_sec
            )
        if found is None:
            tail = '\n'.join(json.dumps(e) for e in self.events[-15:])
            raise WaitTimeoutError(
                f'master: {what}: not within {timeout_sec} s; last events:\n{tail}'
            )
        return found

    def messages(self, topic: str) -> list[dict[str, Any]]:
        with self._changed:
            return [
                e['object'] for e in self.events if e['event'] == 'message' and e['topic'] == topic
            ]

    def dropped(self) -> list[str]:
        with self._changed:
            return [e['text'] for e in self.events if e['event'] == 'dropped']

    def validate_2_0(self, topic: str, document: dict[str, Any]) -> list[Any]:
        """The errors of vda-5050-lib's 2.0 validator for `document` (none: valid)."""
        errors: list[Any] = self.command('validate', topic=topic, object=document)['errors']
        return errors

    def stop(self) -> None:
        if self.process.poll() is None:
            try:
                self.command('stop')
            finally:
                self.process.wait(TIMEOUT_SEC)


# ---- orders and instant actions as a master sends them ----------------------------------


def node(
    node_id: str, sequence_id: int, x: float, y: float, *actions: dict[str, Any]
) -> dict[str, Any]:
    return {
        'nodeId': node_id,
        'sequenceId': sequence_id,
        'released': True,
        'nodePosition': {'x': x, 'y': y, 'mapId': 'demo'},
        'actions': list(actions),
    }


def edge(start: dict[str, Any], end: dict[str, Any]) -> dict[str, Any]:
    return {
        'edgeId': f'{start["nodeId"]}-{end["nodeId"]}',
        'sequenceId': start['sequenceId'] + 1,
        'released': True,
        'startNodeId': start['nodeId'],
        'endNodeId': end['nodeId'],
        'actions': [],
    }


def order(order_id: str, *nodes: dict[str, Any]) -> dict[str, Any]:
    return {
        'orderId': order_id,
        'orderUpdateId': 0,
        'nodes': list(nodes),
        'edges': [edge(a, b) for a, b in itertools.pairwise(nodes)],
    }


def photo(blocking_type: str = 'HARD', camera: str = 'front') -> dict[str, Any]:
    return {
        'actionId': f'photo-{uuid.uuid4().hex[:8]}',
        'actionType': 'take_photo',
        'blockingType': blocking_type,
        'actionParameters': [{'key': 'camera', 'value': camera}],
    }


def instant(action_type: str) -> dict[str, Any]:
    return {'actionId': f'{action_type}-{uuid.uuid4().hex[:8]}', 'actionType': action_type,
            'blockingType': 'HARD'}  # fmt: skip


def with_header(document: dict[str, Any], header_id: int = 1, **header: Any) -> str:
    """`document` as the JSON text of a message to the vehicle (`header` replaces fields of
    its header)."""
    fields = {'headerId': header_id, 'timestamp': timestamp(), 'version': '2.0.0',
              'manufacturer': MANUFACTURER, 'serialNumber': SERIAL, **header}  # fmt: skip
    return json.dumps({**fields, **document})


def processed(master: Master, order_id: str, timeout_sec: float = 30.0) -> dict[str, Any]:
    return master.wait_for(
        lambda e: e['event'] == 'orderProcessed' and e['orderId'] == order_id,
        f'order {order_id} processed',
        timeout_sec,
    )


def instant_state(master: Master, action: dict[str, Any], status: str) -> dict[str, Any]:
    return master.wait_for(
        lambda e: (
            e['event'] == 'instantActionState'
            and e['actionState']['actionId'] == action['actionId']
            and e['actionState']['actionStatus'] == status
        ),
        f'{action["actionType"]} {status}',
    )


def latest_state(master: Master, condition: Any, what: str) -> dict[str, Any]:
    event = master.wait_for(
        lambda e: e['event'] == 'message' and e['topic'] == 'state' and condition(e['object']),
        what,
    )
    state: dict[str, Any] = event['object']
    return state


def ended(client: TaskManagerClient, *task_ids: str) -> list[TaskState]:
    """The states of these tasks once the Task Manager has them all ended (a mission ends just
    after the state that shows its order done)."""

    def states() -> list[TaskState] | None:
        found = client.task_states(list(task_ids))
        done = len(found) == len(task_ids) and all(s.is_final for s in found)
        return sorted(found, key=lambda s: task_ids.index(s.task_id)) if done else None

    result: list[TaskState] = wait_until(states, f'{task_ids} ended', TIMEOUT_SEC)
    return result


def errors_of(master: Master, error_type: str, count: int = 1) -> list[dict[str, Any]]:
    """The errors of `error_type` of the first state that has `count` of them."""

    def found(state: dict[str, Any]) -> list[dict[str, Any]]:
        return [e for e in state['errors'] if e['errorType'] == error_type]

    return found(latest_state(master, lambda s: len(found(s)) == count, error_type))


def refs(error: dict[str, Any]) -> dict[str, str]:
    """An error's references, key: referenceKey, value: referenceValue."""
    return {r['referenceKey']: r['referenceValue'] for r in error.get('errorReferences', [])}
