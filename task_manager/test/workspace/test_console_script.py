"""`task-manager --ros-args --params-file F` starts a node named task_manager."""

from pathlib import Path

import pytest

from task_manager.testing.harness import RosHarness
from task_manager.testing.process import NodeProcess, write_params_file

START_TIMEOUT_SEC = 20.0


@pytest.mark.ros
def test_console_script_starts_the_task_manager_node(ros: RosHarness, tmp_path: Path) -> None:
    params = write_params_file(
        tmp_path / 'params.yaml',
        {
            'tasks': ['fib'],
            'fib': {
                'task_name': 'example/fibonacci',
                'topic': '/fibonacci',
                'msg_interface': 'test_msgs.action.Fibonacci',
            },
        },
    )
    node = NodeProcess(params)
    try:
        node.wait_for_log(r'Task Manager ready', START_TIMEOUT_SEC)
        assert ros.node.wait_for_node('/task_manager', START_TIMEOUT_SEC)
    finally:
        assert node.stop() == 0
