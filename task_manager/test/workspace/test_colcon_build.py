"""A ROS user's `colcon build` of the workspace installs a Task Manager that runs from there.

The venv with the ROS 2 wheels is the underlay: colcon, CMake and the console scripts use
its python, and CMake finds ament_cmake and the rosidl generators under its prefix.

The build base is the workspace's `build/`, colcon's default, where `make install` has built
the interfaces with CMake already: colcon configures each package again (forced) into a new
install space, and what is compiled is not compiled twice (10 s instead of 130-280 s for the
interfaces' C and C++; on a fresh workspace it builds them all).
"""

import json
import os
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from task_manager.testing import process
from task_manager.testing.harness import RosHarness
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import NodeProcess

REPO = Path(__file__).resolve().parents[3]
VENV = Path(sys.prefix)
# The demo packages are left out: their interfaces would double the build time.
PACKAGES = ('task_manager_msgs', 'task_manager')
BUILD_TIMEOUT_SEC = 300.0
PROBE_TIMEOUT_SEC = 30.0
START_TIMEOUT_SEC = 20.0
LOG_TAIL_LINES = 60

# The build comes first in the module's first test: seconds after `make install`, minutes alone.
pytestmark = pytest.mark.timeout(BUILD_TIMEOUT_SEC + 60)

# Where the sourced install space resolves the package from, as JSON on one line.
WHERE_FROM = """
import json
import task_manager
import task_manager_msgs
from ament_index_python.packages import get_package_prefix, get_package_share_directory
print(json.dumps({
    'task_manager': task_manager.__file__,
    'task_manager_msgs': task_manager_msgs.__file__,
    'prefix': get_package_prefix('task_manager'),
    'share': get_package_share_directory('task_manager'),
}))
"""


@dataclass(frozen=True)
class ColconBuild:
    """The outcome of one `colcon build` of the workspace."""

    returncode: int
    log_tail: str
    install: Path


@dataclass(frozen=True)
class InstalledPackage:
    """Where the shell that sourced the install space finds the task_manager package."""

    module_file: Path
    msgs_module_file: Path
    prefix: Path
    share: Path


def _in_sourced_shell(install: Path, *command: str) -> list[str]:
    """`bash -c 'source <install>/setup.bash && exec COMMAND'`, as a ROS user runs things."""
    script = f'source {shlex.quote(str(install / "setup.bash"))} && exec "$@"'
    return ['bash', '-c', script, 'bash', *command]


@pytest.fixture(scope='module')
def colcon_build(tmp_path_factory: pytest.TempPathFactory) -> ColconBuild:
    """Build the workspace's packages once into an install space in a tmp dir (the build
    base is the workspace's own, as a user's `colcon build` has it)."""
    base = tmp_path_factory.mktemp('colcon')
    output = base / 'colcon_output.log'
    command = [
        str(VENV / 'bin' / 'colcon'),
        '--log-base', str(base / 'log'),
        'build',
        '--base-paths', str(REPO),
        '--build-base', str(REPO / 'build'),
        '--install-base', str(base / 'install'),
        '--packages-select', *PACKAGES,
        '--cmake-force-configure',
        '--executor', 'sequential',
        '--cmake-args', f'-DPython3_EXECUTABLE={sys.executable}', '-DBUILD_TESTING=OFF',
    ]  # fmt: skip
    env = dict(
        os.environ,
        PATH=f'{VENV / "bin"}{os.pathsep}{os.environ.get("PATH", "")}',
        # find_package(ament_cmake) searches CMAKE_PREFIX_PATH; the rosidl typesupports
        # are looked up in the ament index of AMENT_PREFIX_PATH.
        CMAKE_PREFIX_PATH=str(VENV),
        AMENT_PREFIX_PATH=str(VENV),
        # No defaults or mixins from the user's ~/.colcon.
        COLCON_HOME=str(base / 'colcon_home'),
    )
    # Without colcon-output there are no per-package logs: keep the console output instead.
    with output.open('w') as out:
        completed = subprocess.run(
            command,
            cwd=base,
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
            timeout=BUILD_TIMEOUT_SEC,
            check=False,
        )
    tail = '\n'.join(output.read_text().splitlines()[-LOG_TAIL_LINES:])
    return ColconBuild(completed.returncode, tail, base / 'install')


@pytest.fixture(scope='module')
def install_space(colcon_build: ColconBuild) -> Path:
    assert colcon_build.returncode == 0, f'colcon build failed:\n{colcon_build.log_tail}'
    return colcon_build.install


@pytest.fixture(scope='module')
def installed_package(install_space: Path) -> InstalledPackage:
    probe = subprocess.run(
        _in_sourced_shell(install_space, sys.executable, '-c', WHERE_FROM),
        capture_output=True,
        text=True,
        timeout=PROBE_TIMEOUT_SEC,
        check=False,
    )
    assert probe.returncode == 0, probe.stdout + probe.stderr
    found = json.loads(probe.stdout.splitlines()[-1])
    return InstalledPackage(
        module_file=Path(found['task_manager']),
        msgs_module_file=Path(found['task_manager_msgs']),
        prefix=Path(found['prefix']),
        share=Path(found['share']),
    )


def test_colcon_builds_the_workspace_into_the_install_space(colcon_build: ColconBuild) -> None:
    assert colcon_build.returncode == 0, f'colcon build failed:\n{colcon_build.log_tail}'
    assert (colcon_build.install / 'setup.bash').is_file()
    for package in PACKAGES:
        index = colcon_build.install / package / 'share' / 'ament_index' / 'resource_index'
        assert (index / 'packages' / package).is_file(), f'{package} is not in the ament index'


def test_sourced_install_space_provides_the_packages_instead_of_the_venvs(
    install_space: Path, installed_package: InstalledPackage
) -> None:
    assert installed_package.prefix == install_space / 'task_manager'
    assert installed_package.module_file.is_relative_to(installed_package.prefix)
    assert installed_package.msgs_module_file.is_relative_to(install_space / 'task_manager_msgs')
    assert (installed_package.share / 'params' / 'task_manager_defaults.yaml').is_file()
    # Where `ros2 run task_manager task-manager` looks, run by the venv's python.
    script = installed_package.prefix / 'lib' / 'task_manager' / 'task-manager'
    shebang = script.read_text().splitlines()[0]
    assert Path(shebang.removeprefix('#!')).resolve() == Path(sys.executable).resolve()


@pytest.mark.ros
def test_installed_task_manager_serves_execute_task(
    ros: RosHarness,
    installed_package: InstalledPackage,
    install_space: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # `ros2 run task_manager task-manager` is not on PyPI: run what it would find, in a
    # shell that sourced the install space, with the parameters file installed beside it.
    executable = installed_package.prefix / 'lib' / 'task_manager' / 'task-manager'
    ros2_run = tmp_path / 'ros2_run_task_manager'
    ros2_run.write_text(
        '#!/bin/bash\n'
        f'source {shlex.quote(str(install_space / "setup.bash"))} || exit 1\n'
        f'exec {shlex.quote(str(executable))} "$@"\n'
    )
    ros2_run.chmod(0o755)
    # NodeProcess runs task_manager_executable(), the venv's console script by default.
    monkeypatch.setattr(process, 'task_manager_executable', lambda: str(ros2_run))
    params_file = installed_package.share / 'params' / 'task_manager_defaults.yaml'

    node = NodeProcess(params_file)
    try:
        node.wait_for_log(r'Task Manager ready', START_TIMEOUT_SEC)
        probe = TaskManagerProbe(ros, START_TIMEOUT_SEC)
        probe.wait_until_connected()
        # One task end to end: a system task, which needs no server.
        result = probe.run('system/wait', {'duration': 0.01})
        probe.destroy()
    finally:
        code = node.stop()
        print('\n'.join(node.log_lines))
    assert (result.task_status, result.error_code) == ('DONE', '')
    assert code == 0
