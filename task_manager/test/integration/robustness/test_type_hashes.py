"""The original interfaces keep their type hashes, so the original's peers still match ours.

ROS 2 (since Iron) refuses to connect a publisher and a subscriber whose type hashes differ.
The hashes below are those of the original definitions (unchanged since the first commit of
task_manager_msgs); adding new types beside them must never change them.
"""

import json
from pathlib import Path

import pytest
from task_manager_msgs.msg import ActiveTaskArray, TaskDoneResult

from task_manager.rclpy_tools import qos
from task_manager.testing.harness import RosHarness
from task_manager.testing.process import LaunchTaskManager, action_task

# key: type name, value: its RIHS01 hash
ORIGINAL_TYPE_HASHES = {
    'task_manager_msgs/msg/ActiveTask': (
        'RIHS01_7093d040983dac27a203494688a692ffe6884c790ff82e434e6928add7c3f303'
    ),
    'task_manager_msgs/msg/ActiveTaskArray': (
        'RIHS01_dc945e8be7e007d5c6246ce560de63c81d548c853439d7d42bbd7adf7e2faee2'
    ),
    'task_manager_msgs/msg/SubtaskGoal': (
        'RIHS01_29f408443de2760eb25fccf7b414f67ca112d28d70bbe2a8e2c6c469064b4f17'
    ),
    'task_manager_msgs/msg/SubtaskResult': (
        'RIHS01_ced5d85509ac4ac831e7d752c443b1e51803e2ba6e0a63212c048b4f300c9350'
    ),
    'task_manager_msgs/msg/TaskDoneResult': (
        'RIHS01_7e5745eee233f776c3bfb8307d45a615b05420de8dae8c24c269d393065357fe'
    ),
    'task_manager_msgs/msg/TaskStatus': (
        'RIHS01_295603cef5b27290b47faf3bd4d927c6118c63045059580e3d55befa5c8c4ab7'
    ),
    'task_manager_msgs/srv/CancelTasks': (
        'RIHS01_421fc3c705d55bc4579e6c11a5d473158122f5fb2dca74e369745549726584ea'
    ),
    'task_manager_msgs/action/ExecuteTask': (
        'RIHS01_86d420378b91da96a33f4e8741b12ae63d248539f07184dc4c9014a4cda63659'
    ),
    'task_manager_msgs/action/Mission': (
        'RIHS01_ab4b0badcadd74a3424a251c3f3ebb214d61aeb0fcc6449fab4620f1db8e79f0'
    ),
    'task_manager_msgs/action/Wait': (
        'RIHS01_88427d37197727bf2a724742d5c81d4573571a2941d6cf5679e9101f03d3b351'
    ),
}


def _installed_hash(type_name: str) -> str:
    """The hash rosidl generated for `type_name`, from its type description in the install."""
    import task_manager_msgs

    package_dir = Path(task_manager_msgs.__file__).resolve().parent
    share = next(
        p / 'share' / 'task_manager_msgs'
        for p in package_dir.parents
        if (p / 'share' / 'task_manager_msgs').is_dir()
    )
    _, kind, name = type_name.split('/')
    description = json.loads((share / kind / f'{name}.json').read_text())
    found = (h['hash_string'] for h in description['type_hashes'] if h['type_name'] == type_name)
    return str(next(found))


@pytest.mark.parametrize('type_name', sorted(ORIGINAL_TYPE_HASHES))
def test_generated_type_hash_is_the_originals(type_name: str) -> None:
    assert _installed_hash(type_name) == ORIGINAL_TYPE_HASHES[type_name]


@pytest.mark.ros
def test_the_node_publishes_the_original_types_on_the_wire(
    ros: RosHarness, launch_task_manager: LaunchTaskManager
) -> None:
    launch_task_manager({'fib': action_task('fib', '/type_hashes/fib')})
    active = ros.record(ActiveTaskArray, '/task_manager/active_tasks', qos.ACTIVE_TASKS)
    results = ros.record(TaskDoneResult, '/task_manager/results', qos.RESULTS)
    active.wait_matched(10.0)
    results.wait_matched(10.0)

    for topic, type_name in (
        ('/task_manager/active_tasks', 'task_manager_msgs/msg/ActiveTaskArray'),
        ('/task_manager/results', 'task_manager_msgs/msg/TaskDoneResult'),
    ):
        publishers = ros.node.get_publishers_info_by_topic(topic)
        assert [str(p.topic_type_hash) for p in publishers] == [ORIGINAL_TYPE_HASHES[type_name]]
