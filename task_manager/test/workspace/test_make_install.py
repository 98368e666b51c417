"""`make install` is incremental: nothing rebuilds unless an input changed."""

import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
STAMPS = REPO / '.venv' / '.stamps'


def _make(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ['make', '--no-print-directory', *args],
        cwd=REPO,
        text=True,
        capture_output=True,
        timeout=600,
        check=False,
    )


def test_second_install_rebuilds_nothing() -> None:
    first = _make('install')
    assert first.returncode == 0, first.stdout + first.stderr
    stamps_before = {p.name: p.stat().st_mtime_ns for p in STAMPS.iterdir()}

    second = _make('install')

    assert second.returncode == 0, second.stdout + second.stderr
    assert "Nothing to be done for 'install'" in second.stdout
    assert not [tool for tool in ('cmake', 'pip', 'bin/uv') if tool in second.stdout]
    assert {p.name: p.stat().st_mtime_ns for p in STAMPS.iterdir()} == stamps_before


def test_changed_msg_file_rebuilds_the_interfaces() -> None:
    # -W pretends the file changed, -n prints what would run without running it.
    dry_run = _make('-n', '-W', 'task_manager_msgs/msg/ActiveTask.msg', 'install')

    assert dry_run.returncode == 0, dry_run.stderr
    assert 'cmake -S task_manager_msgs' in dry_run.stdout
    assert 'ros-wheels' not in dry_run.stdout and 'requirements/ros.txt' not in dry_run.stdout
