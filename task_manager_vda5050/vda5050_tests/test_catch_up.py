"""What the adapter does when task events went missing, without MQTT or ROS: the state of each
task it follows stands in for the events lost (adapter.standing_in), and an order's progress
takes them in any order without going back."""

from typing import Any

import pytest

from task_manager.client import TaskEvent, TaskEventKind, TaskState
from task_manager.core.status import TaskStatus
from task_manager_vda5050.adapter import CAUGHT_UP, standing_in
from task_manager_vda5050.mapping import DEMO_MAPPING, read_mapping
from task_manager_vda5050.orders.plan import Planner
from task_manager_vda5050.orders.running import Orders
from task_manager_vda5050.state.vehicle_state import VehicleState
from task_manager_vda5050.testing import node, order, photo

MAPPING = read_mapping(DEMO_MAPPING)


class StartsAnything:
    """Stands in for the TaskManagerClient: every mission and task starts."""

    def __init__(self) -> None:
        self.started: list[str] = []

    def start_mission(self, _subtasks: list[Any], task_id: str, source: str) -> None:
        self.started.append(task_id)

    def start_task(self, _name: str, _data: Any, task_id: str, source: str) -> None:
        self.started.append(task_id)


def state_of(task_id: str, status: TaskStatus) -> TaskState:
    return TaskState(task_id, 'navigation/navigate_to_pose', status, 'VDA5050', result={})


@pytest.mark.parametrize(
    ('status', 'kind'),
    [
        (TaskStatus.DONE, TaskEventKind.ENDED),
        (TaskStatus.CANCELED, TaskEventKind.ENDED),
        (TaskStatus.ERROR, TaskEventKind.ENDED),
        (TaskStatus.PAUSED, TaskEventKind.PAUSED),
        (TaskStatus.IN_PROGRESS, TaskEventKind.STARTED),
    ],
)
def test_a_state_read_again_stands_in_for_the_event_that_led_to_it(
    status: TaskStatus, kind: TaskEventKind
) -> None:
    event = standing_in(state_of('t', status))

    assert event is not None
    assert (event.kind, event.task.status, event.reason) == (kind, status, CAUGHT_UP)


@pytest.mark.parametrize('status', [TaskStatus.RECEIVED, TaskStatus.QUEUED])
def test_a_task_that_has_not_started_needs_no_event(status: TaskStatus) -> None:
    assert standing_in(state_of('t', status)) is None


def running_order() -> tuple[Orders, VehicleState, str]:
    """An order of three nodes taken (its mission started); its action's id."""
    state = VehicleState()
    orders = Orders(
        StartsAnything(),  # type: ignore[arg-type]
        Planner(MAPPING, {'navigation/navigate_to_pose'}.__contains__),
        state,
        None,
    )
    action = photo()
    orders.receive(
        order('o', node('a', 0, 0.0, 0.0), node('b', 2, 1.0, 0.0), node('c', 4, 2.0, 0.0, action))
    )
    return orders, state, action['actionId']


def ended(task_id: str) -> TaskEvent:
    return standing_in(state_of(task_id, TaskStatus.DONE))  # type: ignore[return-value]


def test_the_order_follows_its_steps_the_tasks_beside_then_its_mission() -> None:
    orders, _, action_id = running_order()

    assert orders.followed() == ['o/a/0', 'o/b/2', 'o/c/4', f'o/{action_id}', 'o']
    orders.on_event(ended('o/a/0'))
    assert orders.followed() == ['o/b/2', 'o/c/4', f'o/{action_id}', 'o']


def test_a_drive_whose_end_comes_late_does_not_take_the_vehicle_back() -> None:
    orders, state, _ = running_order()
    orders.on_event(ended('o/b/2'))

    orders.on_event(ended('o/a/0'))  # its ENDED lost, then read again

    assert (state.last_node_id, state.last_node_sequence_id) == ('b', 2)
    assert [n['nodeId'] for n in state.node_states] == ['c']


def test_an_event_read_again_after_the_end_changes_nothing() -> None:
    orders, state, _ = running_order()
    orders.on_event(ended('o/a/0'))

    orders.on_event(standing_in(state_of('o/a/0', TaskStatus.IN_PROGRESS)))  # type: ignore[arg-type]

    assert not state.driving
