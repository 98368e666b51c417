"""Our interfaces travel over real DDS between real rclpy clients and servers."""

from typing import Any

from rclpy.action.server import ActionServer, ServerGoalHandle
from rclpy.client import Client
from task_manager_msgs.action import ExecuteTask
from task_manager_msgs.srv import CancelTasks

from task_manager.testing.harness import RosHarness, wait_for_future

TIMEOUT_SEC = 10.0


def test_execute_task_goal_and_result_cross_dds(ros: RosHarness) -> None:
    received: list[ExecuteTask.Goal] = []

    def execute(goal_handle: ServerGoalHandle[Any, Any, Any]) -> ExecuteTask.Result:
        received.append(goal_handle.request)
        goal_handle.succeed()
        return ExecuteTask.Result(
            task_id=goal_handle.request.task_id,
            task_result='{"sequence": [0, 1]}',
            task_status='DONE',
            error_code='',
        )

    server = ActionServer(ros.node, ExecuteTask, '/round_trip/execute_task', execute)
    client = ros.action_client(ExecuteTask, '/round_trip/execute_task')
    assert client.wait_for_server(timeout_sec=TIMEOUT_SEC)
    goal = ExecuteTask.Goal(
        task_id='id-1', task_name='example/fibonacci', source='CLI', task_data='{"order": 1}'
    )
    goal_handle = wait_for_future(ros.send_goal(client, goal), TIMEOUT_SEC, 'goal response')
    assert goal_handle.accepted
    result = wait_for_future(goal_handle.get_result_async(), TIMEOUT_SEC, 'result').result

    assert received[0].task_data == '{"order": 1}' and received[0].source == 'CLI'
    assert (result.task_id, result.task_result, result.task_status, result.error_code) == (
        'id-1',
        '{"sequence": [0, 1]}',
        'DONE',
        '',
    )
    ros.destroy(client, server)


def test_cancel_tasks_request_and_response_cross_dds(ros: RosHarness) -> None:
    def cancel(
        request: CancelTasks.Request, response: CancelTasks.Response
    ) -> CancelTasks.Response:
        response.successful_cancels = [i for i in request.cancelled_tasks if i != 'stuck']
        response.success = len(response.successful_cancels) == len(request.cancelled_tasks)
        return response

    service = ros.node.create_service(CancelTasks, '/round_trip/cancel_tasks', cancel)
    client: Client[CancelTasks.Request, CancelTasks.Response] = ros.node.create_client(
        CancelTasks, '/round_trip/cancel_tasks'
    )
    assert client.wait_for_service(timeout_sec=TIMEOUT_SEC)
    request = CancelTasks.Request(cancelled_tasks=['a', 'stuck', 'b'])
    response = wait_for_future(client.call_async(request), TIMEOUT_SEC, 'cancel response')

    assert response.success is False
    assert list(response.successful_cancels) == ['a', 'b']
    ros.node.destroy_client(client)
    ros.node.destroy_service(service)
