"""enable_task_servers: every task also at /task_manager/task/<task_name>, same machinery."""

import threading
import time

from rclpy.client import Client
from std_srvs.srv import SetBool
from test_msgs.action import Fibonacci

from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.testing.harness import RosHarness, wait_for_future
from task_manager.testing.process import LaunchTaskManager, action_task, service_task
from task_manager.testing.servers import ScriptedActionServer, ScriptedService

TIMEOUT_SEC = 15.0
FEEDBACK_REPEAT_SEC = 0.2


def test_task_servers_run_tasks_through_the_task_manager(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    ScriptedActionServer(
        ros.node,
        Fibonacci,
        f'{topic_prefix}/fib',
        on_goal=lambda goal: goal.succeed(Fibonacci.Result(sequence=[0, 1, 1, 2])),
    )
    ScriptedService(
        ros.node,
        SetBool,
        f'{topic_prefix}/set',
        on_call=lambda call: call.respond(success=True, message='set'),
    )
    tm = launch_task_manager(
        {
            'fib': action_task('math/fib', f'{topic_prefix}/fib'),
            'set': service_task('set', f'{topic_prefix}/set'),
        },
        enable_task_servers=True,
    )
    action_client = ros.action_client(Fibonacci, '/task_manager/task/math/fib')
    service_client: Client[SetBool.Request, SetBool.Response] = ros.node.create_client(
        SetBool, '/task_manager/task/set'
    )
    assert wait_until_ready(action_client.server_is_ready, TIMEOUT_SEC)
    assert wait_until_ready(service_client.service_is_ready, TIMEOUT_SEC)

    goal_handle = wait_for_future(
        ros.send_goal(action_client, Fibonacci.Goal(order=4)), TIMEOUT_SEC, 'goal'
    )
    action_result = wait_for_future(goal_handle.get_result_async(), TIMEOUT_SEC, 'result')
    response = wait_for_future(
        service_client.call_async(SetBool.Request(data=True)), TIMEOUT_SEC, 'response'
    )

    assert list(action_result.result.sequence) == [0, 1, 1, 2]
    assert (response.success, response.message) == (True, 'set')
    published = tm.results.wait_until(
        lambda msgs: (
            (ours := [m for m in msgs if m.source == 'task_server']) and len(ours) >= 2 and ours
        ),
        TIMEOUT_SEC,
    )
    assert sorted((m.task_name, m.task_status, m.source) for m in published) == [
        ('math/fib', 'DONE', 'task_server'),
        ('set', 'DONE', 'task_server'),
    ]
    ros.destroy(action_client)


def test_feedback_of_an_action_task_reaches_the_task_servers_client(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/fib')
    launch_task_manager(
        {'fib': action_task('fib', f'{topic_prefix}/fib')}, enable_task_servers=True
    )
    client = ros.action_client(Fibonacci, '/task_manager/task/fib')
    assert wait_until_ready(client.server_is_ready, TIMEOUT_SEC)
    received: list[list[int]] = []
    got_feedback = threading.Event()

    def on_feedback(message: Fibonacci.Impl.FeedbackMessage) -> None:
        received.append(list(message.feedback.sequence))
        got_feedback.set()

    goal_handle = wait_for_future(
        ros.send_goal(client, Fibonacci.Goal(order=2), on_feedback),
        TIMEOUT_SEC,
        'goal',
    )
    goal = server.wait_for_goals(1, TIMEOUT_SEC)[0]
    # Feedback is volatile: one published before both feedback topics have matched their
    # subscribers (discovery runs on after the goal is accepted) is lost, as in ROS. The
    # server publishes the same feedback again until it arrives, as a real server would.
    deadline = time.monotonic() + TIMEOUT_SEC
    while not got_feedback.is_set() and time.monotonic() < deadline:
        goal.publish_feedback(Fibonacci.Feedback(sequence=[0, 1]))
        got_feedback.wait(FEEDBACK_REPEAT_SEC)

    assert got_feedback.is_set()
    goal.succeed(Fibonacci.Result(sequence=[0, 1, 1]))
    result = wait_for_future(goal_handle.get_result_async(), TIMEOUT_SEC, 'result')
    assert set(map(tuple, received)) == {(0, 1)}
    assert list(result.result.sequence) == [0, 1, 1]
