"""The bridge between a real Task Manager and a real mosquitto, driven by the FleetClient."""

import pytest

from task_manager.testing.gateway import check
from task_manager_mqtt.fleet_client import FleetClient
from task_manager_mqtt.testing import ROBOT

pytestmark = pytest.mark.ros


def test_a_task_and_a_mission_from_the_cloud(online: FleetClient) -> None:
    task = online.start_task(ROBOT, 'instant', {'data': True})
    reply = check(task.accepted(), 'mqtt_reply')
    assert reply['ok'] and reply['task_id'] == task.task_id and not reply['duplicate']
    result = check(task.result(), 'task')
    assert (result['task_id'], result['status'], result['source']) == (
        task.task_id,
        'DONE',
        'CLOUD',
    )
    assert result['sequence'] > 0 and result['result'] == {'success': True, 'message': ''}

    mission = online.start_mission(
        ROBOT, [{'task_name': 'instant', 'task_data': {'data': True}}] * 2
    )
    assert len(check(mission.accepted(), 'mqtt_reply')['subtask_ids']) == 2
    ended = mission.result()
    assert (ended['task_name'], ended['status']) == ('system/mission', 'DONE'), ended

    robot = online.robots[ROBOT]
    check(robot.connection, 'mqtt_connection')
    assert {t['task_name'] for t in robot.tasks} >= {'fib', 'instant', 'system/mission'}
