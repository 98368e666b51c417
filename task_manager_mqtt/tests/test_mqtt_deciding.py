"""What decides what runs (issue 29) through the bridge, a real mosquitto and a real node: a
start's options, the ops reprioritize and why, and the reason of an event, from the FleetClient."""

from typing import Any

import pytest

from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check, wait_until
from task_manager_mqtt.fleet_client import FleetClient
from task_manager_mqtt.fleet_types import FleetError
from task_manager_mqtt.testing import ROBOT

pytestmark = pytest.mark.ros


def test_a_start_with_a_timeout_ends_error_timeout_and_why_says_so(
    robot: Robot, online: FleetClient
) -> None:
    events: list[dict[str, Any]] = []
    online.on_event(lambda _, event: events.append(check(event, 'task_event')))

    task = online.start_task(ROBOT, 'fib', {'order': 1}, priority=4, timeout_sec=0.5)

    result = check(task.result(), 'task')
    assert (result['status'], result['error_code'], result['priority']) == ('ERROR', 'timeout', 4)
    assert robot.fib.wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()
    decisions = [check(d, 'decision') for d in online.why(ROBOT, task.task_id)]
    assert decisions[-1]['decision'] == 'timeout'
    assert result['decisions'] == decisions
    ended = wait_until(
        lambda: [
            e for e in events if e['event'] == 'ENDED' and e['task']['task_id'] == task.task_id
        ],
        'the ENDED event',
    )
    assert ended[0]['reason'] == decisions[-1]['reason']


def test_reprioritize_a_running_task_and_a_mission_started_with_its_options(
    robot: Robot, online: FleetClient
) -> None:
    task = online.start_task(ROBOT, 'fib', {'order': 1}, on_conflict='queue')
    check(task.accepted(), 'mqtt_reply')
    goal = robot.fib.wait_for_goals(1, TIMEOUT_SEC)[0]

    changed = check(online.reprioritize(ROBOT, [task.task_id, 'ghost'], 9), 'task')

    assert (changed['task_name'], changed['status'], changed['source']) == (
        'system/reprioritize',
        'ERROR',
        'CLOUD',
    )
    assert changed['result']['successful_changes'] == [task.task_id]
    assert 'ghost' in changed['result']['errors'][0]
    assert online.why(ROBOT, task.task_id)[-1]['decision'] == 'reprioritized'
    goal.succeed()
    assert (task.result()['status'], task.result()['priority']) == ('DONE', 9)
    mission = online.start_mission(
        ROBOT, [{'task_name': 'instant', 'task_data': {'data': True}}], priority=2
    )
    assert (mission.result()['status'], mission.result()['priority']) == ('DONE', 2)


def test_why_of_an_unknown_task_and_an_unusable_option_are_error_replies(
    online: FleetClient,
) -> None:
    with pytest.raises(FleetError) as unknown:
        online.why(ROBOT, 'nobody')
    reply = check(
        online.request(ROBOT, 'start_task', task_name='fib', priority='high').result(TIMEOUT_SEC),
        'mqtt_reply',
    )
    queued = online.start_task(ROBOT, 'fib', {'order': 1}, on_conflict='wait')

    assert unknown.value.code == 'unknown_task_id'
    assert "'nobody'" in str(unknown.value)
    assert not reply['ok']
    assert (reply['error']['code'], reply['error']['field']) == ('invalid_request', 'priority')
    with pytest.raises(FleetError) as refused:
        queued.accepted()
    assert refused.value.code == 'invalid_request' and 'on_conflict' in str(refused.value)
