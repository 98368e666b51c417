"""The FleetClient's results, each passed on once: one delivered again after a reconnection is
not, and a robot whose history began again (sequence numbers it sent before, other tasks) is
still heard. No broker: the receiver is given the messages a broker would deliver."""

import json
from concurrent.futures import Future

from task_manager_mqtt.fleet.passed_results import RECENT_RESULTS
from task_manager_mqtt.fleet.receiving import FleetReceiver
from task_manager_mqtt.fleet_types import Document
from task_manager_mqtt.settings import DEFAULT_PREFIX
from task_manager_mqtt.topics import Topics

ROBOT = 'robot1'
RESULT_TOPIC = Topics(DEFAULT_PREFIX, ROBOT).result


def _receiver() -> tuple[FleetReceiver, list[tuple[int, str]]]:
    receiver = FleetReceiver(DEFAULT_PREFIX, lambda mid, qos: None)
    passed: list[tuple[int, str]] = []
    receiver.result_callbacks.append(
        lambda _, task: passed.append((task['sequence'], task['task_id']))
    )
    return receiver, passed


def _deliver(receiver: FleetReceiver, sequence: int, task_id: str) -> None:
    task = {'task_id': task_id, 'status': 'DONE', 'sequence': sequence}
    receiver.receive(RESULT_TOPIC, json.dumps(task).encode())


def test_a_result_delivered_again_is_passed_on_once() -> None:
    receiver, passed = _receiver()
    for sequence in (1, 2, 3, 2, 3):
        _deliver(receiver, sequence, f'a{sequence}')

    assert passed == [(1, 'a1'), (2, 'a2'), (3, 'a3')]
    assert receiver.robots[ROBOT].duplicates == 2


def test_a_robot_whose_history_began_again_is_still_heard() -> None:
    receiver, passed = _receiver()
    for sequence in range(1, 6):
        _deliver(receiver, sequence, f'old{sequence}')
    awaited: Future[Document] = Future()
    receiver.expect_result(ROBOT, 'new2', awaited)

    for sequence in (1, 2, 2):  # the reinstalled robot's first results, the last delivered again
        _deliver(receiver, sequence, f'new{sequence}')

    assert passed[5:] == [(1, 'new1'), (2, 'new2')]
    assert awaited.result(0)['task_id'] == 'new2'
    assert (receiver.robots[ROBOT].duplicates, receiver.robots[ROBOT].last_sequence) == (1, 2)


def test_a_result_delivered_again_far_behind_the_newest_is_still_known() -> None:
    receiver, passed = _receiver()
    newest = 3 * RECENT_RESULTS
    for sequence in range(1, newest + 1):
        _deliver(receiver, sequence, f't{sequence}')

    for sequence in range(newest - RECENT_RESULTS + 1, newest + 1):  # the whole window again
        _deliver(receiver, sequence, f't{sequence}')

    assert len(passed) == newest
    assert receiver.robots[ROBOT].duplicates == RECENT_RESULTS
