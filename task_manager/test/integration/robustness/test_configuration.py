"""Parameters files: defaults, number forms, and errors that stop the node (BEHAVIOUR.md)."""

from pathlib import Path
from typing import Any

import pytest

from task_manager.testing.process import NodeProcess, action_task, service_task, write_params_file

EXIT_TIMEOUT_SEC = 20.0
EXIT_CONFIGURATION_ERROR = 2

CONFIGURATION_ERRORS: dict[str, tuple[dict[str, Any], str]] = {
    'missing topic': (
        {
            'tasks': ['nav'],
            'nav': {'task_name': 'navigate', 'msg_interface': 'test_msgs.action.Fibonacci'},
        },
        r"task 'navigate': nav\.topic is missing",
    ),
    'missing tasks': ({'enable_task_servers': False}, r"parameter 'tasks' is missing"),
    'listed but not declared': (
        {'tasks': ['ghost'], 'other': action_task('x', '/x')},
        r"task 'ghost'",
    ),
    'unknown interface package': (
        {'tasks': ['nav'], 'nav': action_task('navigate', '/n', 'no_such_msgs.action.Nope')},
        r"task 'navigate': unknown msg_interface no_such_msgs/action/Nope",
    ),
    'unknown interface name': (
        {'tasks': ['nav'], 'nav': action_task('navigate', '/n', 'test_msgs/action/Nope')},
        r"task 'navigate': unknown msg_interface test_msgs/action/Nope",
    ),
    'malformed interface': (
        {'tasks': ['nav'], 'nav': action_task('navigate', '/n', 'Fibonacci')},
        r"task 'navigate': msg_interface 'Fibonacci' is not of the form",
    ),
    'success field not a bool': (
        {'tasks': ['s'], 's': service_task('set', '/s', service_success_field='message')},
        r"task 'set': service_success_field 'message' is not a bool field",
    ),
    'success field missing': (
        {'tasks': ['s'], 's': service_task('set', '/s', service_success_field='ok')},
        r"task 'set': service_success_field 'ok' is not a bool field",
    ),
    'duplicate names': (
        {'tasks': ['a', 'b'], 'a': action_task('same', '/a'), 'b': action_task('same', '/b')},
        r"task 'same': declared twice",
    ),
    'node parameter of the wrong type': (
        {'tasks': ['a'], 'a': action_task('nav', '/a'), 'server_wait_timeout': 'soon'},
        r"parameter 'server_wait_timeout' must be int or float",
    ),
    'history path that cannot be written': (
        {'tasks': ['a'], 'a': action_task('nav', '/a'), 'history_path': '/proc/no/h.sqlite'},
        r'cannot open the task history /proc/no/h\.sqlite',
    ),
    'wrong type': (
        {'tasks': ['a'], 'a': action_task('nav', '/a', blocking='yes')},
        r"task 'nav': a\.blocking must be bool",
    ),
}


@pytest.mark.parametrize('case', list(CONFIGURATION_ERRORS))
def test_bad_configuration_stops_the_node_with_one_clear_line(tmp_path: Path, case: str) -> None:
    parameters, expected = CONFIGURATION_ERRORS[case]
    process = NodeProcess(write_params_file(tmp_path / 'params.yaml', parameters))

    exit_code = process.wait_exit(EXIT_TIMEOUT_SEC)

    assert exit_code == EXIT_CONFIGURATION_ERROR, process.log_lines
    assert len(process.log_lines) == 1, process.log_lines
    assert 'invalid configuration' in process.log_lines[0]
    process.wait_for_log(expected, 0.1)
    assert 'Traceback' not in process.log_lines[0]


def test_numbers_in_either_form_and_omitted_options_are_accepted(tmp_path: Path) -> None:
    parameters = {
        'tasks': ['a', 'b'],
        'a': action_task('a', '/a', cancel_timeout=2),
        'b': action_task('b', '/b', cancel_timeout=0.5, blocking=True),
        'server_wait_timeout': 1,
    }
    process = NodeProcess(write_params_file(tmp_path / 'params.yaml', parameters))
    try:
        process.wait_for_log(r'Task Manager ready with 2 task\(s\): a, b', EXIT_TIMEOUT_SEC)
    finally:
        assert process.stop() == 0
