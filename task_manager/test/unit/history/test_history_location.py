"""The default history file: one per ROS domain and node; the file of before is adopted once."""

import os
from pathlib import Path

import pytest

from task_manager.core.history.location import (
    adopt_legacy_history,
    default_history_path,
    legacy_history_path,
    ros_home,
)
from task_manager.core.history.store import HistoryInUseError, HistoryQuery, TaskHistory
from task_manager.core.status import TaskStatus
from task_manager.core.task import TaskRecord
from task_manager.core.task_spec import InterfaceName, TaskKind, TaskSpec

FIB = TaskSpec('fib', '/fib', InterfaceName('test_msgs', TaskKind.ACTION, 'Fibonacci'))


def test_each_domain_and_node_has_its_own_file_under_ros_home() -> None:
    assert default_history_path('/h', 0, '/task_manager') == (
        '/h/task_manager/domain0/task_manager/history.sqlite'
    )
    assert default_history_path('/h', 92, '/task_manager') == (
        '/h/task_manager/domain92/task_manager/history.sqlite'
    )
    assert default_history_path('/h', 92, '/robot1/task_manager') == (
        '/h/task_manager/domain92/robot1/task_manager/history.sqlite'
    )
    assert legacy_history_path('/h') == '/h/task_manager/history.sqlite'


def test_ros_home_is_the_variable_or_dot_ros_in_the_home_folder(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv('HOME', str(tmp_path))
    monkeypatch.setenv('ROS_HOME', '/elsewhere')
    assert ros_home() == '/elsewhere'
    monkeypatch.delenv('ROS_HOME')
    assert ros_home() == str(tmp_path / '.ros')
    monkeypatch.setenv('ROS_HOME', '')
    assert ros_home() == str(tmp_path / '.ros')


def _history_with(path: Path, task_id: str) -> None:
    history = TaskHistory(str(path))
    record = TaskRecord(task_id, FIB, 'CLI', task_data='{}', received_at=1.0)
    record.mark_started(now=1.5)
    record.mark_ended(TaskStatus.DONE, {}, now=2.0)
    history.write(record)
    history.flush()
    history.close()


def _task_ids(path: Path) -> list[str]:
    history = TaskHistory(str(path))
    try:
        return [row.task_id for row in history.query(HistoryQuery())]
    finally:
        history.close()


def test_the_file_of_before_moves_to_the_first_default_file_that_has_none(tmp_path: Path) -> None:
    legacy = tmp_path / 'task_manager' / 'history.sqlite'
    _history_with(legacy, 'from-before')
    Path(f'{legacy}-wal').write_bytes(b'')  # as a killed node leaves it
    new = tmp_path / 'task_manager' / 'domain7' / 'task_manager' / 'history.sqlite'

    assert adopt_legacy_history(str(legacy), str(new))

    assert _task_ids(new) == ['from-before']
    assert sorted(os.listdir(legacy.parent)) == ['domain7']  # nothing left behind, lock included
    other = tmp_path / 'task_manager' / 'domain8' / 'task_manager' / 'history.sqlite'
    assert not adopt_legacy_history(str(legacy), str(other))  # moved once only
    assert not other.exists()


def test_a_node_that_has_its_own_file_keeps_it_and_leaves_the_file_of_before(
    tmp_path: Path,
) -> None:
    legacy, new = tmp_path / 'old.sqlite', tmp_path / 'domain0' / 'history.sqlite'
    _history_with(legacy, 'from-before')
    _history_with(new, 'its-own')

    assert not adopt_legacy_history(str(legacy), str(new))

    assert (_task_ids(legacy), _task_ids(new)) == (['from-before'], ['its-own'])


def test_the_file_of_before_stays_while_a_running_task_manager_holds_it(tmp_path: Path) -> None:
    legacy, new = tmp_path / 'old.sqlite', tmp_path / 'domain0' / 'history.sqlite'
    _history_with(legacy, 'from-before')
    running = TaskHistory(str(legacy))
    try:
        with pytest.raises(HistoryInUseError, match=f'pid {os.getpid()}'):
            adopt_legacy_history(str(legacy), str(new))
    finally:
        running.close()

    assert legacy.exists() and not new.exists()
