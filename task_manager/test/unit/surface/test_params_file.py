"""The parameters-file check that runs before rcl reads the file."""

from pathlib import Path

import pytest

from task_manager.core.errors import ConfigurationError
from task_manager.core.params_file import check_params_file, params_files


def _file(tmp_path: Path, text: str) -> Path:
    path = tmp_path / 'params.yaml'
    path.write_text(text)
    return path


def test_params_files_are_found_in_the_ros_arguments() -> None:
    arguments = [
        'task-manager',
        '--ros-args',
        '--params-file',
        'a.yaml',
        '-p',
        'x:=1',
        '--params-file',
        'b.yaml',
    ]

    assert params_files(arguments) == [Path('a.yaml'), Path('b.yaml')]
    assert params_files(['task-manager', '--params-file']) == []


@pytest.mark.parametrize(
    ('value', 'problem'),
    [
        ('[]', 'an empty list has no type'),
        ('[1, "x"]', 'mixes int, str'),
        ('[1, 2.5]', 'mixes float, int'),
        ('[true, 1]', 'mixes bool, int'),
        ('2.2e-309', 'subnormal'),
        ('[1.5, 2.2e-309]', 'subnormal'),
        ('{}', 'an empty mapping is no value'),
    ],
)
def test_values_ros_cannot_hold_are_named(tmp_path: Path, value: str, problem: str) -> None:
    path = _file(tmp_path, f'task_manager:\n  ros__parameters:\n    nav:\n      odd: {value}\n')

    with pytest.raises(ConfigurationError, match=problem) as raised:
        check_params_file(path)

    assert "'task_manager.ros__parameters.nav.odd'" in str(raised.value)


@pytest.mark.parametrize(
    ('key', 'hint'),
    [
        ('resources', 'leave resources out for a task that holds none'),
        ('retry:\n        on_error_codes', 'leave on_error_codes out to retry after any error'),
    ],
)
def test_an_empty_list_of_a_task_entry_says_what_to_write_instead(
    tmp_path: Path, key: str, hint: str
) -> None:
    path = _file(tmp_path, f'task_manager:\n  ros__parameters:\n    nav:\n      {key}: []\n')

    with pytest.raises(ConfigurationError) as raised:
        check_params_file(path)

    assert str(raised.value).endswith(
        'an empty list has no type; ROS parameters need at least one element; ' + hint
    )


def test_a_valid_file_passes(tmp_path: Path) -> None:
    path = _file(
        tmp_path,
        'task_manager:\n  ros__parameters:\n    tasks: [a, b]\n    a: {cancel_timeout: 1}\n'
        '    weights: [0.5, 1.5]\n',
    )

    check_params_file(path)


def test_unreadable_or_malformed_files_are_configuration_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigurationError, match='cannot read parameters file'):
        check_params_file(tmp_path / 'missing.yaml')
    with pytest.raises(ConfigurationError, match='cannot read parameters file'):
        check_params_file(_file(tmp_path, 'task_manager: [unclosed'))
