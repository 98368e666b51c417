"""Fixtures of the adapter's tests: a real mosquitto, the demo robot and its Task Manager,
the adapter as users run it, and the independent master control (npm's vda-5050-lib)."""

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from task_manager_mqtt.settings import DEFAULT_MAX_PAYLOAD_BYTES
from vda5050.model.base import VDA5050Model
from vda5050.model.connection import Connection
from vda5050.model.factsheet import Factsheet
from vda5050.model.state import State
from vda5050.model.visualization import Visualization

from task_manager.client import TaskManagerClient
from task_manager_demo.testing import demo_robot as demo_robot_and_task_manager
from task_manager_vda5050.broker import MASTER_USER
from task_manager_vda5050.schemas import problems
from task_manager_vda5050.testing import (
    MANUFACTURER,
    SERIAL,
    TESTER,
    AdapterProcess,
    BrokerProcess,
    Master,
)

# fast enough for short tests, slow enough that a 40 m leg is still driving when paused
ROBOT_SPEEDS = ('linear_speed:=8.0', 'angular_speed:=20.0')


@pytest.fixture(scope='module')
def demo_robot(ros_context: None) -> Iterator[TaskManagerClient]:
    """The simulated robot and a Task Manager with the demo's tasks (for the module), and a
    client of it."""
    with demo_robot_and_task_manager('vda5050_test', *ROBOT_SPEEDS) as client:
        yield client


@pytest.fixture
def broker(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[BrokerProcess]:
    """A mosquitto for the vehicle, the master and the tester; its largest message is the
    bridges' 1 MiB, or the test's parameter (`indirect`)."""
    limit = getattr(request, 'param', DEFAULT_MAX_PAYLOAD_BYTES)
    broker = BrokerProcess(
        tmp_path / 'broker', MANUFACTURER, [SERIAL], [MASTER_USER, TESTER], max_payload_bytes=limit
    )
    broker.start()
    yield broker
    broker.stop()


@pytest.fixture
def adapter(demo_robot: TaskManagerClient, broker: BrokerProcess) -> Iterator[AdapterProcess]:
    adapter = AdapterProcess(broker)
    yield adapter
    code = adapter.stop()
    assert adapter.killed or code == 0, '\n'.join(adapter.log_lines)


@pytest.fixture
def master(broker: BrokerProcess, adapter: AdapterProcess) -> Iterator[Master]:
    """The master control, once the vehicle is ONLINE; at the end, every message it received
    was valid for it (none dropped) and against the 2.0.0 and the 2.1.0 schemas."""
    master = Master(broker, MASTER_USER)
    try:
        master.wait_for(
            lambda e: (
                e['event'] == 'message'
                and e['topic'] == 'connection'
                and e['object']['connectionState'] == 'ONLINE'
            ),
            'ONLINE',
        )
        yield master
        check_every_message(master)
    finally:
        master.stop()


# key: topic, value: the SDK's model of its messages (2.1)
SDK_MODELS: dict[str, type[VDA5050Model]] = {
    'state': State,
    'connection': Connection,
    'factsheet': Factsheet,
    'visualization': Visualization,
}


def check_every_message(master: Master) -> None:
    """Valid for vda-5050-lib (none dropped, and its 2.0 validators), against the 2.1.0
    schemas, and read by the SDK's models back into the same message."""
    assert master.dropped() == []
    seen: list[tuple[str, dict[str, Any]]] = [
        (e['topic'], e['object']) for e in master.events if e['event'] == 'message'
    ]
    assert seen
    for topic, document in seen:
        assert problems(topic, document) == [], (topic, document)
        assert master.validate_2_0(topic, document) == [], (topic, document)
        assert SDK_MODELS[topic].model_validate(document).to_wire() == document
