"""One Task Manager per ROS domain: a second one refuses to start, the first goes on."""

import re
import socket
import subprocess
from pathlib import Path
from typing import Any

import rclpy
from rclpy.executors import SingleThreadedExecutor
from task_manager_msgs.msg import TaskManagerInstance
from test_msgs.action import Fibonacci

from task_manager.core.names import INSTANCES_TOPIC
from task_manager.ros.instances import (
    INSTANCES_QOS,
    INSTANCES_SUBSCRIPTION_QOS,
    InstanceWatch,
    this_instance,
)
from task_manager.testing.harness import RosHarness
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import (
    LaunchTaskManager,
    NodeProcess,
    action_task,
    write_params_file,
)
from task_manager.testing.servers import ScriptedActionServer

EXIT_TIMEOUT_SEC = 20.0
EXIT_ANOTHER_TASK_MANAGER = 2
TWIN_LINE = (
    r'\[FATAL\].*(not starting|stopping): another Task Manager already serves '
    r'/task_manager/execute_task on ROS domain \d+ \(pid {pid} on host .*\); stop it first'
)


def _first(ros: RosHarness, launch: LaunchTaskManager, prefix: str) -> TaskManagerProbe:
    ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/fib', on_goal=lambda g: g.succeed())
    probe: TaskManagerProbe = launch({'fib': action_task('fib', f'{prefix}/fib')})
    return probe


def _second(tmp_path: Path, prefix: str, **parameters: object) -> NodeProcess:
    tasks = {'fib': action_task('fib', f'{prefix}/fib')}
    params = {'tasks': list(tasks), **tasks, **parameters}
    return NodeProcess(write_params_file(tmp_path / 'second.yaml', params))


def _pid(probe: TaskManagerProbe) -> int:
    return int(probe.process.process.pid)  # type: ignore[attr-defined]


def _refused(second: NodeProcess) -> tuple[int, list[str]]:
    try:
        code = second.wait_exit(EXIT_TIMEOUT_SEC)
    except subprocess.TimeoutExpired:
        second.stop()
        raise AssertionError(
            f'the second Task Manager did not stop within {EXIT_TIMEOUT_SEC} s; its log:\n'
            + '\n'.join(second.log_lines)
        ) from None
    return code, [line for line in second.log_lines if '[FATAL]' in line]


def test_a_second_task_manager_refuses_to_start_and_the_first_goes_on(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, tmp_path: Path
) -> None:
    first = _first(ros, launch_task_manager, topic_prefix)

    code, fatal = _refused(_second(tmp_path, topic_prefix))

    assert code == EXIT_ANOTHER_TASK_MANAGER
    assert len(fatal) == 1 and re.search(TWIN_LINE.format(pid=_pid(first)), fatal[0]), fatal
    assert first.run('fib', {'order': 1}, task_id='after').task_status == 'DONE'


def test_without_a_wait_before_serving_the_younger_still_stops(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, tmp_path: Path
) -> None:
    first = _first(ros, launch_task_manager, topic_prefix)

    # no wait before serving: the younger serves until discovery brings the older one's
    # announcement (almost always after it has started serving), then stops
    code, fatal = _refused(_second(tmp_path, topic_prefix, instance_check_timeout=0))

    assert code == EXIT_ANOTHER_TASK_MANAGER
    assert len(fatal) == 1 and re.search(TWIN_LINE.format(pid=_pid(first)), fatal[0]), fatal
    assert first.run('fib', {'order': 1}, task_id='after').task_status == 'DONE'


def test_each_task_manager_announces_itself(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    first = _first(ros, launch_task_manager, topic_prefix)
    instances = ros.record(TaskManagerInstance, INSTANCES_TOPIC, INSTANCES_SUBSCRIPTION_QOS)

    announced = instances.wait_until(
        lambda msgs: next((m for m in msgs if m.pid == _pid(first)), None),
        EXIT_TIMEOUT_SEC,
        'the first Task Manager on /task_manager/instances',
    )

    assert announced.host == socket.gethostname()
    assert announced.started.sec > 0 and announced.instance_id


def test_an_older_announcement_arriving_just_before_the_own_one_is_still_seen(
    ros: RosHarness,
) -> None:
    """The race behind the meeting tests' rare failures, made to happen every time: the older
    Task Manager's announcement reaches the younger's new subscription before the younger has
    published its own. With a depth of 1 its own replaced the older's, which was then never
    seen (and, acknowledged, never sent again)."""
    older = this_instance()
    older.started.sec -= 60
    older_publisher = ros.node.create_publisher(TaskManagerInstance, INSTANCES_TOPIC, INSTANCES_QOS)
    younger = rclpy.create_node('younger_task_manager')
    create_publisher = younger.create_publisher

    def publishing_the_older_first(*args: Any, **kwargs: Any) -> Any:
        publisher = create_publisher(*args, **kwargs)
        publish_own = publisher.publish

        def publish(own: Any) -> None:
            older_publisher.publish(older)  # same process: in the subscription when this returns
            publish_own(own)

        publisher.publish = publish  # type: ignore[method-assign,assignment]
        return publisher

    younger.create_publisher = publishing_the_older_first  # type: ignore[method-assign]
    executor = SingleThreadedExecutor()
    executor.add_node(younger)
    try:
        watch = InstanceWatch(younger)
        executor.spin_until_future_complete(watch.older, timeout_sec=EXIT_TIMEOUT_SEC)

        seen = watch.older.result() if watch.older.done() else None
        assert seen is not None, 'the younger never saw the older announcement'
        assert seen.instance_id == older.instance_id
    finally:
        executor.shutdown()
        younger.destroy_node()
        ros.node.destroy_publisher(older_publisher)
