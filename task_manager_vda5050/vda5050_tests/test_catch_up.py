"""What the adapter does when task events went missing, without MQTT or ROS: the state of each
task it follows stands in for the events lost (adapter.standing_in), an order's progress takes
them in any order without going back, and the adapter's worker does it when its client says
events were lost. (Through real DDS, a process stopped while the node floods it: see the
closing note of 2026-11-30, the client at times heard nothing more at all.)"""

import queue
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from typing import Any

import pytest

from task_manager import TaskManagerUnavailable
from task_manager.client import TaskEvent, TaskEventKind, TaskState
from task_manager.core.status import TaskStatus
from task_manager_vda5050 import adapter as adapter_module
from task_manager_vda5050.adapter import CAUGHT_UP, Adapter, standing_in
from task_manager_vda5050.mapping import DEMO_MAPPING, read_mapping
from task_manager_vda5050.orders.plan import Planner
from task_manager_vda5050.orders.running import Orders
from task_manager_vda5050.state.vehicle_state import VehicleState
from task_manager_vda5050.testing import MANUFACTURER, SERIAL, node, order, photo, with_header
from task_manager_vda5050.topics import Vehicle

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


def test_an_action_of_a_node_whose_reaching_is_learnt_late_fails_unstarted() -> None:
    """A NONE action starts once its node is reached; learnt only after a later node (the
    drive's ENDED lost, then read again), the vehicle has left: FAILED, never started."""
    client, state = StartsAnything(), VehicleState()
    orders = Orders(
        client,  # type: ignore[arg-type]
        Planner(MAPPING, {'navigation/navigate_to_pose'}.__contains__),
        state,
        None,
    )
    action = photo('NONE')
    orders.receive(
        order('o', node('a', 0, 0.0, 0.0), node('b', 2, 1.0, 0.0, action), node('c', 4, 2.0, 0.0))
    )
    orders.on_event(ended('o/c/4'))

    orders.on_event(ended('o/b/2'))

    (action_state,) = state.document()['actionStates']
    assert action_state['actionStatus'] == 'FAILED'
    assert 'reaching node b was learnt after a later node' in action_state['resultDescription']
    assert client.started == ['o']  # its mission, and no photo


def test_an_event_read_again_after_the_end_changes_nothing() -> None:
    orders, state, _ = running_order()
    orders.on_event(ended('o/a/0'))

    orders.on_event(standing_in(state_of('o/a/0', TaskStatus.IN_PROGRESS)))  # type: ignore[arg-type]

    assert not state.driving


class FollowsNothing(StartsAnything):
    """Stands in for the adapter's client: its callbacks kept for the test to call, and the
    states it answers `task_states` with."""

    def __init__(self) -> None:
        super().__init__()
        self.on_event: list[Any] = []
        self.on_lost: list[Any] = []
        self.states: dict[str, TaskState] = {}
        self.unavailable = 0
        self.active_at_start: list[TaskState] = []
        self.cancelled: list[tuple[list[str], str]] = []
        """How many reads of the states fail before they are answered."""
        self.asked = 0

    def on_task_event(self, callback: Any) -> None:
        self.on_event.append(callback)

    def on_events_lost(self, callback: Any) -> None:
        self.on_lost.append(callback)

    def task_states(self, task_ids: list[str] | None = None) -> list[TaskState]:
        if not task_ids:  # every active task: what ran before the adapter started
            return list(self.active_at_start)
        self.asked += 1
        if self.unavailable:
            self.unavailable -= 1
            raise TaskManagerUnavailable('/task_manager/get_task_states is not available')
        return [self.states[i] for i in task_ids if i in self.states]

    def cancel_tasks(self, task_ids: list[str], *, source: str) -> None:
        self.cancelled.append((task_ids, source))


class StateLink:
    """Stands in for the adapter's MQTT link: the states it would send."""

    def __init__(self) -> None:
        self.vehicle = Vehicle(MANUFACTURER, SERIAL)
        self.largest_payload = 1_000_000
        self.sent: queue.SimpleQueue[dict[str, Any]] = queue.SimpleQueue()

    def room(self) -> int:
        return self.largest_payload

    def publish(self, topic: str, fields: dict[str, Any]) -> None:
        if topic == 'state':
            self.sent.put(fields)


def test_the_adapter_reads_its_tasks_again_when_its_client_lost_events() -> None:
    """The adapter as it runs (its worker thread), with its client's callbacks: told that
    events were lost, it asks the states of the order's tasks and takes their ends."""
    client, link = FollowsNothing(), StateLink()
    with order_running(client, link):
        assert client.started == ['o']
        client.states = {i: state_of(i, TaskStatus.DONE) for i in ('o/a/0', 'o/b/2', 'o')}

        for lost in client.on_lost:
            lost(7)

        done = until_state(link, lambda s: s['lastNodeId'] == 'b')
        assert (done['driving'], done['nodeStates'], done['edgeStates']) == (False, [], [])


@contextmanager
def order_running(client: FollowsNothing, link: StateLink) -> Iterator[Adapter]:
    """The adapter as it runs (its worker thread) with order `o` (nodes a, b) taken; stopped
    after."""
    adapter = Adapter(client, [], link, MAPPING)  # type: ignore[arg-type]
    adapter.start()
    try:
        payload = with_header(order('o', node('a', 0, 0.0, 0.0), node('b', 2, 1.0, 0.0)))
        adapter.on_message('order', payload.encode())
        until_state(link, lambda s: s['orderId'] == 'o')
        yield adapter
    finally:
        adapter.stop()


def test_a_read_that_failed_is_made_again_until_one_is_answered(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The Task Manager unavailable when the adapter reads its tasks again: it reads them
    again a moment later (CATCH_UP_AGAIN_SEC), and takes their ends then."""
    monkeypatch.setattr(adapter_module, 'CATCH_UP_AGAIN_SEC', 0.1)
    client, link = FollowsNothing(), StateLink()
    with order_running(client, link):
        client.states = {i: state_of(i, TaskStatus.DONE) for i in ('o/a/0', 'o/b/2', 'o')}
        client.unavailable = 2

        for lost in client.on_lost:
            lost(7)

        done = until_state(link, lambda s: s['lastNodeId'] == 'b')
        assert (done['driving'], done['nodeStates'], client.asked) == (False, [], 3)


def test_tasks_of_an_earlier_adapter_are_cancelled_at_start_and_state_says_so() -> None:
    """The adapter started again while its earlier process's order ran in the Task Manager:
    those tasks (source VDA5050) are cancelled, the others left alone, and state.errors has
    a warning for the master."""
    client, link = FollowsNothing(), StateLink()
    client.active_at_start = [
        state_of('o', TaskStatus.IN_PROGRESS),
        state_of('o/a/0', TaskStatus.IN_PROGRESS),
        TaskState('other', 'camera/take_photo', TaskStatus.IN_PROGRESS, 'CLI', result={}),
    ]
    client.active_at_start[1] = replace(client.active_at_start[1], source='mission')
    adapter = Adapter(client, [], link, MAPPING)  # type: ignore[arg-type]
    adapter.start()
    try:
        first = until_state(link, lambda s: True)
        assert client.cancelled == [(['o'], 'VDA5050')]
        assert [(e['errorType'], e['errorLevel']) for e in first['errors']] == [
            ('orderLost', 'WARNING')
        ]
    finally:
        adapter.stop()


def until_state(link: StateLink, condition: Any) -> dict[str, Any]:
    """The first state sent that meets `condition` (within 10 s)."""
    while not condition(state := link.sent.get(timeout=10.0)):
        pass
    return state
