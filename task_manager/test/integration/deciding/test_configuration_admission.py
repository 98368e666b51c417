"""Parameters files with the keys that decide what runs (issue 29), read by a real node."""

from pathlib import Path

from task_manager.testing.process import NodeProcess, action_task, service_task, write_params_file

START_TIMEOUT_SEC = 20.0
EXIT_CONFIGURATION_ERROR = 2


def test_a_broken_retry_map_stops_the_node_with_one_clear_line(tmp_path: Path) -> None:
    entry = action_task('navigate', '/n', retry={'max_attempts': 3, 'on_error_codes': ['oops']})
    parameters = {'tasks': ['nav'], 'nav': entry, 'history_path': ''}
    process = NodeProcess(write_params_file(tmp_path / 'params.yaml', parameters))

    exit_code = process.wait_exit(START_TIMEOUT_SEC)

    assert exit_code == EXIT_CONFIGURATION_ERROR, process.log_lines
    assert len(process.log_lines) == 1, process.log_lines
    process.wait_for_log(
        r"invalid configuration.*task 'navigate': nav\.retry\.on_error_codes must name some of "
        r"aborted, task_start_failed, timeout, got 'oops'",
        0.1,
    )


def test_a_file_with_every_new_key_is_served(tmp_path: Path) -> None:
    parameters = {
        'tasks': ['nav', 'photo'],
        'nav': action_task(
            'navigate',
            '/n',
            resources=['base'],
            priority=2,
            on_conflict='queue',
            timeout_sec=60,
            queue_timeout_sec=10.0,
            feedback_timeout_sec=5,
            retry={'max_attempts': 3, 'initial_delay_sec': 0.5, 'on_error_codes': ['aborted']},
        ),
        'photo': service_task('photo', '/p', resources=['camera']),
        'max_queued': 10,
        'source_priorities': {'joystick': 100, 'CLOUD': 10},
        'history_path': '',
        'instance_check_timeout': 0,
    }
    process = NodeProcess(write_params_file(tmp_path / 'params.yaml', parameters))
    try:
        process.wait_for_log(r'Task Manager ready with 2 task\(s\): navigate, photo', 20.0)
        assert not [line for line in process.log_lines if 'WARN' in line], process.log_lines
    finally:
        assert process.stop() == 0
