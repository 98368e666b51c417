"""Fixtures that start the Task Manager as users do and talk to it over DDS."""

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from task_manager.testing.harness import RosHarness
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import LaunchTaskManager, NodeProcess, write_params_file

START_TIMEOUT_SEC = 20.0
# Serve at once: each test's node is alone on the test run's domain (the tests of two Task
# Managers meeting, test_instances.py, keep the default wait).
NO_INSTANCE_CHECK = {'instance_check_timeout': 0}


@pytest.fixture
def topic_prefix(request: pytest.FixtureRequest) -> str:
    """A prefix unique to the test, so servers of earlier tests are never matched."""
    return f'/t{abs(hash(request.node.nodeid)) % 10**8}'


@pytest.fixture
def node_wrapper() -> list[str] | None:
    """A command that runs the node (see NodeProcess); a test module may give one."""
    return None


@pytest.fixture
def launch_task_manager(
    ros: RosHarness, tmp_path: Path, node_wrapper: list[str] | None
) -> Iterator[LaunchTaskManager]:
    """Start `task-manager --ros-args --params-file F` with the given task entries."""
    processes: list[NodeProcess] = []
    probes: list[TaskManagerProbe] = []

    def launch(tasks: dict[str, dict[str, Any]], **node_parameters: Any) -> TaskManagerProbe:
        # each node its own history, so that no test sees another's results
        history = {'history_path': str(tmp_path / f'history{len(processes)}.sqlite')}
        parameters = {
            'tasks': list(tasks),
            **tasks,
            **history,
            **NO_INSTANCE_CHECK,
            **node_parameters,
        }
        params_file = write_params_file(tmp_path / f'params{len(processes)}.yaml', parameters)
        process = NodeProcess(params_file, wrapper=node_wrapper)
        processes.append(process)
        process.wait_for_log(r'Task Manager ready', START_TIMEOUT_SEC)
        probe = TaskManagerProbe(ros)
        probes.append(probe)
        probe.wait_until_connected()
        probe.process = process  # type: ignore[attr-defined]
        return probe

    yield launch
    for probe in probes:
        probe.destroy()
    for process in processes:
        code = process.stop()
        process.print_output()
        assert code == 0 or process.killed
