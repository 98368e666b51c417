"""Task events a client fell too far behind for, over real DDS: told as lost by the callback
and in their place by the iterator of events and losses. The batches are published by the test
(a stand-in for the node's writer, the same topic and QoS)."""

import threading
from collections.abc import Iterator
from typing import Any

import pytest
from rclpy.qos import QoSProfile, ReliabilityPolicy
from task_manager_msgs.msg import ActiveTaskArray, TaskEventArray

from task_manager.client import EventsLost, TaskManagerClient
from task_manager.core.names import ACTIVE_TASKS_TOPIC, TASK_EVENT_BATCHES_TOPIC
from task_manager.rclpy_tools import qos
from task_manager.testing.gateway import wait_until
from task_manager.testing.harness import RosHarness
from task_manager.testing.lost_events import batch_writer, event_batch

pytestmark = pytest.mark.ros
TIMEOUT_SEC = 15.0
DRAINED_SEC = 1.0
"""How long an iterator read after its last item is known to have come waits for more."""


@pytest.fixture
def client() -> Iterator[TaskManagerClient]:
    with TaskManagerClient('test_events_lost', timeout_sec=TIMEOUT_SEC) as client:
        yield client


def test_events_a_client_fell_too_far_behind_for_are_told_as_lost(
    ros: RosHarness, client: TaskManagerClient
) -> None:
    """A client held up while more batches come than its reader keeps (1,000) loses the
    oldest: it is told how many, after the events that came, from the numbers the middleware
    gives each message. The batches here are published by the test (a stand-in for the
    node's writer, the same topic and QoS)."""
    count = 3 * qos.DEEP_QUEUE_DEPTH
    beside = ros.record(
        TaskEventArray,
        TASK_EVENT_BATCHES_TOPIC,
        QoSProfile(depth=2 * count, reliability=ReliabilityPolicy.RELIABLE),
    )
    seen: list[str] = []
    lost: list[int] = []
    held, released = threading.Event(), threading.Event()

    def take(event: Any) -> None:
        seen.append(event.task.task_id)
        if event.task.task_id == 'hold':
            held.set()
            released.wait(TIMEOUT_SEC)

    client.on_task_event(take)
    client.on_events_lost(lost.append)
    followed = client.task_events(timeout_sec=DRAINED_SEC, losses=True)
    writer = batch_writer(ros, readers=2)  # the client's and the recorder beside it
    try:
        writer.publish(event_batch('hold'))
        assert held.wait(TIMEOUT_SEC), 'the client never got the first batch'
        for number in range(count):
            writer.publish(event_batch(f'b{number}'))
        beside.wait_until(lambda messages: len(messages) == count + 1, TIMEOUT_SEC, 'all sent')
    finally:
        released.set()

    wait_until(lambda: seen and seen[-1] == f'b{count - 1}', 'the last batch taken')
    taken = seen[1:]
    assert taken == sorted(taken, key=lambda task_id: int(task_id[1:])), 'out of order'
    assert lost, 'no loss told'
    assert len(taken) + sum(lost) == count, (len(taken), lost)
    # the iterator: the same events, and each loss right after the first event past its gap
    items = list(followed)
    assert [i.task.task_id for i in items if not isinstance(i, EventsLost)] == seen
    numbers: list[int] = []  # of the events so far ('hold' is -1, b0 0)
    gaps: list[int] = []  # the batches missing between the two events before each loss
    for item in items:
        if isinstance(item, EventsLost):
            gaps.append(numbers[-1] - numbers[-2] - 1)
        else:
            numbers.append(-1 if item.task.task_id == 'hold' else int(item.task.task_id[1:]))
    assert [i for i in items if isinstance(i, EventsLost)] == [EventsLost(n) for n in lost]
    assert gaps == lost


def _active_list_writer(ros: RosHarness) -> Any:
    """A stand-in for the node's writer of /task_manager/active_tasks (its topic and QoS)."""
    return ros.on_executor(
        lambda: ros.node.create_publisher(ActiveTaskArray, ACTIVE_TASKS_TOPIC, qos.ACTIVE_TASKS)
    )


def test_events_that_reach_the_client_after_the_node_did_are_told_as_maybe_lost(
    ros: RosHarness, client: TaskManagerClient
) -> None:
    """A node started (or started again) reaches a client's reader of its active list before
    its reader of the events (11-18 ms here): whoever read the node's state once it was
    reached missed what the events said meanwhile, and no number shows it (a new writer).
    The client tells it as a loss of a number not known (0)."""
    lost: list[int] = []
    client.on_events_lost(lost.append)
    _active_list_writer(ros)
    wait_until(lambda: client.connected, 'the client reached by the active list')
    assert not client.events_connected and lost == []
    batch_writer(ros)
    wait_until(lambda: lost, 'the loss told')
    assert lost == [0] and client.events_connected


def test_events_that_reach_the_client_before_the_node_did_lose_nothing(
    ros: RosHarness, client: TaskManagerClient
) -> None:
    lost: list[int] = []
    seen: list[str] = []
    client.on_events_lost(lost.append)
    client.on_task_event(lambda event: seen.append(event.task.task_id))
    writer = batch_writer(ros)
    wait_until(lambda: client.events_connected, 'the client reached by the events')
    _active_list_writer(ros)
    wait_until(lambda: client.connected, 'the client reached by the active list')
    writer.publish(event_batch('after'))
    wait_until(lambda: seen == ['after'], 'the batch after taken')
    assert lost == []
