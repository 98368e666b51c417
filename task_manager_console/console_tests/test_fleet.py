"""The Fleet on a real mosquitto, with simulated robots (each speaks its bridge's MQTT protocol,
no ROS): robots appear by themselves, silent ones show, each result is stored once and in
order, nothing is lost while the console or its database is away, bad messages are counted."""

import json
import logging
from collections.abc import Callable
from typing import Any

import pytest
from task_manager_mqtt.fleet_types import FleetError

from task_manager_console.fleet import Fleet
from task_manager_console.robots import ConnectionState, RobotState
from task_manager_console.simulation.robot import SimulatedRobot
from task_manager_console.simulation.robot_loop import TIMEOUT_SEC
from task_manager_console.store.fleet_history import HistoryFilter
from task_manager_console.store.local_postgres import PostgresServer
from task_manager_console.testing import ROBOTS, Results

StartConsole = Callable[..., Fleet]
StartRobot = Callable[..., SimulatedRobot]


def robot_is(fleet: Fleet, robot_id: str, check: Callable[[RobotState], bool]) -> bool:
    return fleet.wait_for(
        lambda robots: robot_id in robots and check(robots[robot_id]), TIMEOUT_SEC
    )


def sequences(fleet: Fleet, robot_id: str) -> list[int]:
    """The robot's stored sequences, oldest first."""
    found = fleet.history.query(HistoryFilter(robot_id=robot_id, limit=10_000))
    return [document['sequence'] for document in reversed(found)]


def test_every_robot_appears_without_configuration(
    start_console: StartConsole, start_robot_on: StartRobot
) -> None:
    first = start_robot_on('robot1', tasks=['fib', 'dock'])  # before the console: retained
    fleet = start_console()
    start_robot_on('robot2')  # after it
    assert robot_is(fleet, 'robot1', lambda r: r.online and r.since is not None)
    assert robot_is(fleet, 'robot2', lambda r: r.online)
    robot1 = fleet.robots['robot1']
    assert robot1.connection_state == ConnectionState.ONLINE and not robot1.silent
    assert [t['task_name'] for t in robot1.tasks] == ['fib', 'dock']
    assert robot1.declares('dock') and not fleet.robots['robot2'].declares('dock')
    assert sorted(fleet.robots) == ['robot1', 'robot2']  # robot3 never connected

    waiting = {'task_id': 'c1', 'task_name': 'system/confirm', 'source': 'CLOUD'}
    queued = {'task_id': 'q1', 'task_name': 'fib', 'source': 'CLOUD', 'queue_position': 1}
    first.set_active(
        [{**waiting, 'status': 'IN_PROGRESS'}, {**queued, 'status': 'QUEUED'}], omitted=3
    )
    assert robot_is(fleet, 'robot1', lambda r: len(r.active) == 2)
    robot1 = fleet.robots['robot1']
    assert [(t['task_id'], t['status']) for t in robot1.active] == [
        ('c1', 'IN_PROGRESS'),
        ('q1', 'QUEUED'),
    ]
    assert robot1.active_omitted == 3
    assert robot1.document()['active'][1]['queue_position'] == 1


def test_a_robot_that_goes_silent_is_shown_as_such(
    start_console: StartConsole, start_robot_on: StartRobot
) -> None:
    fleet = start_console()
    vanishing, cut_off, stopping = (start_robot_on(r) for r in ROBOTS)
    assert all(robot_is(fleet, r, lambda s: s.online) for r in ROBOTS)
    online_since = fleet.robots['robot1'].since

    vanishing.vanish()  # the broker publishes its bridge's last will
    assert robot_is(fleet, 'robot1', lambda r: r.connection_state == 'CONNECTIONBROKEN')
    broken = fleet.robots['robot1']
    assert broken.silent and not broken.online
    assert broken.since is not None and online_since is not None and broken.since > online_since

    cut_off.set_connection('ONLINE', task_manager_connected=False)  # no Task Manager behind
    assert robot_is(fleet, 'robot2', lambda r: r.silent)
    assert fleet.robots['robot2'].connection_state == ConnectionState.ONLINE

    stopping.go_offline()  # a clean stop: not silent, OFFLINE
    assert robot_is(
        fleet, 'robot3', lambda r: r.connection_state == 'OFFLINE' and r.since is not None
    )
    assert not fleet.robots['robot3'].silent
    assert fleet.robots['robot3'].document()['silent'] is False


def test_each_result_is_stored_once_and_in_order(
    start_console: StartConsole, start_robot_on: StartRobot
) -> None:
    fleet = start_console()
    results = Results(fleet)
    robot = start_robot_on('robot1')
    sent = robot.send_results(300)
    for task in sent[250:]:  # delivered again, as after a reconnection
        robot.publish(robot.topics.result, task)
    robot.send_results(1)
    stored = results.wait(301)
    assert [d['sequence'] for d in stored] == list(range(1, 302))
    assert sequences(fleet, 'robot1') == list(range(1, 302))
    assert fleet.history.count() == 301
    assert fleet.duplicates == 50
    assert robot_is(fleet, 'robot1', lambda r: (r.last_result or {}).get('sequence') == 301)
    assert fleet.robots['robot1'].results_stored == 301
    assert fleet.results_waiting() == 0


def test_results_sent_while_the_console_was_away_are_stored_when_it_is_back(
    start_console: StartConsole, start_robot_on: StartRobot
) -> None:
    first = start_console()  # its session on the broker starts here
    robot = start_robot_on('robot1')
    Results(first).wait(len(robot.send_results(5)))
    first.close()
    robot.send_results(40)  # the broker keeps them for the console's session
    again = start_console()
    assert again.wait_until(lambda: again.results_stored == 40, TIMEOUT_SEC)
    assert sequences(again, 'robot1') == list(range(1, 46))
    assert again.robots['robot1'].last_result is not None


def test_a_robots_bad_messages_never_stop_the_console(
    start_console: StartConsole,
    start_robot_on: StartRobot,
    caplog: pytest.LogCaptureFixture,
) -> None:
    fleet = start_console(max_message_bytes=10_000)
    results = Results(fleet)
    robot = start_robot_on('robot1')
    assert robot_is(fleet, 'robot1', lambda r: r.online)
    topics = robot.topics
    bad: list[tuple[str, Any]] = [
        (topics.result, b'{"task_id": '),  # not JSON
        (topics.result, b'[1, 2]'),  # not an object
        (topics.result, b'[' * 40 + b']' * 40),  # nested too deep
        (topics.result, b'{"pad": "' + b'x' * 20_000 + b'"}'),  # over the console's limit
        (topics.result, {**robot.task(), 'task_name': 'fib\nforged line'}),
        (topics.result, {**robot.task(), 'sequence': 0}),  # no history: no key to store it by
        (topics.tasks, {'timestamp': 'now', 'tasks': 'fib'}),
        (topics.active_tasks, {'timestamp': '2026-01-01T00:00:00Z', 'tasks': [{'id': 1}]}),
        (
            topics.connection,
            {'robot_id': 'robot2', 'connection_state': 'OFFLINE', 'timestamp': 'x'},
        ),
        (topics.connection, {'connection_state': 'ASLEEP'}),
    ]
    with caplog.at_level(logging.WARNING, logger='task_manager_console'):
        for topic, payload in bad:
            robot.publish(topic, payload)
        robot.send_results(1)
        [stored] = results.wait(1)
    assert stored['sequence'] == robot.sequence  # the one good result, after the bad ones
    assert fleet.bad_messages.per_robot == {'robot1': len(bad)}
    assert fleet.robots['robot1'].bad_messages == len(bad)
    state = fleet.robots['robot1']
    assert state.online and [t['task_name'] for t in state.tasks] == ['fib']  # as before
    lines = [r.getMessage() for r in caplog.records if 'robot robot1' in r.getMessage()]
    assert len(lines) == 1, lines  # at most once a minute per robot
    assert 'logged at most once a minute' in lines[0]
    assert '\n' not in lines[0]


def test_actions_need_a_known_robot_online_and_usable_names(
    start_console: StartConsole, start_robot_on: StartRobot
) -> None:
    fleet = start_console()
    start_robot_on('robot1').go_offline()
    assert robot_is(
        fleet, 'robot1', lambda r: r.connection_state == 'OFFLINE' and r.since is not None
    )
    refusals: dict[str, Callable[[], object]] = {
        'robot_offline': lambda: fleet.start_task('robot1', 'fib'),
        'unknown_robot': lambda: fleet.client.cancel('robot9', ['t1']),
        'invalid_request': lambda: fleet.start_task('robot\x071', 'fib'),
    }
    for code, act in refusals.items():
        with pytest.raises(FleetError) as refused:
            act()
        assert refused.value.code == code, refused.value
    with pytest.raises(FleetError, match=r'task_name contains the character U\+000A'):
        fleet.start_task('robot1', 'fib\nx')
    with pytest.raises(FleetError, match="task_ids names 't1' more than once"):
        fleet.client.pause('robot1', ['t1', 't1'])
    with pytest.raises(FleetError, match='robot robot1 is OFFLINE since '):
        fleet.client.stop('robot1')
    answers = fleet.stop_all(timeout_sec=1.0)  # not asked: it is OFFLINE
    assert list(answers) == ['robot1']
    assert answers['robot1']['ok'] is False
    assert answers['robot1']['error']['code'] == 'robot_offline'


ON_POSTGRESQL = pytest.mark.parametrize('database_url', ['postgresql'], indirect=True)
"""A database server that stops and starts again."""


@ON_POSTGRESQL
def test_results_wait_with_the_broker_while_the_database_is_away(
    postgres: PostgresServer, start_console: StartConsole, start_robot_on: StartRobot
) -> None:
    fleet = start_console()
    results = Results(fleet)
    robot = start_robot_on('robot1')
    results.wait(len(robot.send_results(10)))
    postgres.stop()
    try:
        robot.send_results(30)
        assert fleet.wait_until(lambda: not fleet.database_up, TIMEOUT_SEC)
    finally:
        postgres.start()
    results.wait(40)  # stored when it is back, by the same console
    assert fleet.database_up
    assert sequences(fleet, 'robot1') == list(range(1, 41))


@ON_POSTGRESQL
def test_results_not_stored_stay_with_the_broker_across_a_restart(
    postgres: PostgresServer, start_console: StartConsole, start_robot_on: StartRobot
) -> None:
    fleet = start_console()
    robot = start_robot_on('robot1')
    results = Results(fleet)
    results.wait(len(robot.send_results(10)))
    postgres.stop()
    try:
        robot.send_results(30)
        received = lambda: fleet.results_received == 40 and not fleet.database_up  # noqa: E731
        assert fleet.wait_until(received, TIMEOUT_SEC)  # it has them, and cannot store them
        fleet.close()  # never stored: never acknowledged
    finally:
        postgres.start()
    again = start_console()
    assert again.wait_until(lambda: again.results_stored == 30, TIMEOUT_SEC)
    assert sequences(again, 'robot1') == list(range(1, 41))


def test_a_robot_id_with_control_characters_is_never_listed(
    start_console: StartConsole, caplog: pytest.LogCaptureFixture
) -> None:
    """As the MQTT client hands the console a message (no broker account can be named so)."""
    fleet = start_console()
    robot = SimulatedRobot(0, 'robot\n1', 'unused')
    with caplog.at_level(logging.WARNING, logger='task_manager_console'):
        for name, document in (
            ('connection', robot.connection_document('ONLINE')),
            ('result', robot.task()),
        ):
            topic = f'{robot.topics.prefix}/robot\n1/{name}'
            fleet.client._dispatch(topic, json.dumps(document).encode(), 1, 1)
        assert fleet.wait_until(lambda: fleet.bad_messages.total == 2, TIMEOUT_SEC)
    assert fleet.robots == {}
    assert fleet.history.count() == 0
    [line] = [r.getMessage() for r in caplog.records]
    assert line.startswith('robot robot\\u000a1: a message on connection ignored (1 so far')
