"""One Task Manager per ROS domain: a second one refuses to start, the first goes on."""

import re
import socket
import subprocess
from pathlib import Path

from task_manager_msgs.msg import TaskManagerInstance
from test_msgs.action import Fibonacci

from task_manager.ros.instances import INSTANCES_QOS, INSTANCES_TOPIC
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
    return launch({'fib': action_task('fib', f'{prefix}/fib')})


def _second(tmp_path: Path, prefix: str, **parameters: object) -> NodeProcess:
    tasks = {'fib': action_task('fib', f'{prefix}/fib')}
    params = {'tasks': list(tasks), **tasks, **parameters}
    return NodeProcess(write_params_file(tmp_path / 'second.yaml', params))


def _pid(probe: TaskManagerProbe) -> int:
    return probe.process.process.pid  # type: ignore[attr-defined]


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
    instances = ros.record(TaskManagerInstance, INSTANCES_TOPIC, INSTANCES_QOS)

    announced = instances.wait_until(
        lambda msgs: next((m for m in msgs if m.pid == _pid(first)), None),
        EXIT_TIMEOUT_SEC,
        'the first Task Manager on /task_manager/instances',
    )

    assert announced.host == socket.gethostname()
    assert announced.started.sec > 0 and announced.instance_id
