"""A robot's state from its bridge's documents, checked against the protocol; the count and the
log of bad messages; where the fleet history lives by default. Pure Python, no broker."""

import logging
from datetime import UTC, datetime, timedelta

import pytest

from task_manager_console.bad_messages import LOG_INTERVAL_SEC, BadMessages
from task_manager_console.robots import (
    BadDocumentError,
    ConnectionState,
    RobotState,
    robot_id_problem,
)
from task_manager_console.store.location import default_database_url

T0 = datetime(2026, 3, 1, 8, 0, tzinfo=UTC)


def connection(state: str, at: datetime = T0, reaches: bool = True) -> dict[str, object]:
    return {
        'robot_id': 'robot1',
        'connection_state': state,
        'timestamp': at.isoformat(),
        'task_manager_connected': reaches,
    }


def test_since_is_the_first_documents_time_then_when_the_state_changed() -> None:
    seen = RobotState('robot1').with_connection(connection('ONLINE', T0))
    assert (seen.connection_state, seen.since) == (ConnectionState.ONLINE, T0)
    again = seen.with_connection(connection('ONLINE', T0 + timedelta(hours=1)))
    assert again.since == T0  # the same state: since is kept
    later = T0 + timedelta(hours=2)
    # the last will carries the time it was set (the connection's): since is when it came
    broken = again.with_connection(connection('CONNECTIONBROKEN', T0, reaches=False), now=later)
    assert (broken.connection_state, broken.since, broken.silent) == (
        ConnectionState.CONNECTIONBROKEN,
        later,
        True,
    )


@pytest.mark.parametrize(
    ('state', 'reaches', 'silent', 'online'),
    [
        ('ONLINE', True, False, True),
        ('ONLINE', False, True, False),
        ('CONNECTIONBROKEN', False, True, False),
        ('OFFLINE', False, False, False),
    ],
)
def test_silent_and_online(state: str, reaches: bool, silent: bool, online: bool) -> None:
    robot = RobotState('robot1').with_connection(connection(state, reaches=reaches))
    assert (robot.silent, robot.online) == (silent, online)
    assert robot.document()['silent'] is silent


def test_declared_and_active_tasks_are_read_as_the_protocol_has_them() -> None:
    robot = RobotState('robot1').with_tasks(
        {
            'timestamp': T0.isoformat(),
            'tasks': [{'task_name': 'fib', 'msg_interface': 'x/action/Fibonacci'}],
            'omitted': 2,
        }
    )
    assert robot.declares('fib') and not robot.declares('dock')
    assert robot.tasks[0]['pause'] == 'none' and robot.tasks_omitted == 2
    task = {'task_id': 'a', 'task_name': 'fib', 'source': 'CLOUD', 'status': 'PAUSED'}
    robot = robot.with_active({'timestamp': T0.isoformat(), 'tasks': [task], 'omitted': 0})
    assert [(t['task_id'], t['status']) for t in robot.active] == [('a', 'PAUSED')]


@pytest.mark.parametrize(
    ('change', 'document', 'why'),
    [
        ('with_connection', {**connection('ONLINE'), 'connection_state': 'ASLEEP'}, 'connection'),
        ('with_connection', {**connection('ONLINE'), 'robot_id': 'robot2'}, "robot_id 'robot2'"),
        ('with_connection', [1], 'connection'),
        ('with_tasks', {'timestamp': T0.isoformat(), 'tasks': 'fib'}, 'tasks'),
        ('with_active', {'timestamp': T0.isoformat(), 'tasks': [{'task_id': 1}]}, 'active_tasks'),
        ('with_active', {'timestamp': T0.isoformat(), 'tasks': [], 'omitted': -1}, 'active_tasks'),
    ],
)
def test_a_document_that_does_not_fit_the_protocol_changes_nothing(
    change: str, document: object, why: str
) -> None:
    robot = RobotState('robot1').with_connection(connection('ONLINE'))
    with pytest.raises(BadDocumentError, match=why):
        getattr(robot, change)(document)


@pytest.mark.parametrize(
    ('robot_id', 'problem'),
    [
        ('robot1', ''),
        ('robot\n1', 'robot_id contains the character U+000A at position 5'),
        ('r\u202eobot', 'robot_id contains the character U+202E'),
        ('r' * 257, 'robot_id has 257 characters; at most 256 are allowed'),
        ('a/b', 'must be one topic level, without + # /'),
        ('', 'must be one topic level'),
    ],
)
def test_robot_ids_with_control_characters_are_refused(robot_id: str, problem: str) -> None:
    found = robot_id_problem(robot_id)
    assert (problem in found) if problem else found == ''


def test_bad_messages_are_counted_and_logged_once_per_robot_per_minute(
    caplog: pytest.LogCaptureFixture,
) -> None:
    now = [100.0]
    bad = BadMessages(logging.getLogger('test.bad'), clock=lambda: now[0])
    with caplog.at_level(logging.WARNING, logger='test.bad'):
        for _ in range(5):
            bad.count('robot1', 'result', 'not JSON')
        bad.count('robot\n2', 'tasks', 'not an object\nforged')
        now[0] += LOG_INTERVAL_SEC - 1
        bad.count('robot1', 'result', 'not JSON')
        now[0] += 1
        bad.count('robot1', 'result', 'too large')
    assert bad.total == 8 and bad.per_robot == {'robot1': 7, 'robot\n2': 1}
    lines = [record.getMessage() for record in caplog.records]
    assert len(lines) == 3
    assert lines[0].startswith('robot robot1: a message on result ignored (1 so far')
    assert lines[1].startswith('robot robot\\u000a2: a message on tasks ignored (1 so far')
    assert lines[2].startswith('robot robot1: a message on result ignored (7 so far')
    assert all('\n' not in line for line in lines)


def test_the_fleet_history_is_under_ros_home_by_default(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv('ROS_HOME', '/srv/ros')
    assert default_database_url() == 'sqlite:////srv/ros/task_manager/console/fleet.sqlite'
