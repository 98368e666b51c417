"""A parameters file with the keys that decide what runs, read as the node reads it.

No node runs: rclpy's own YAML reader flattens the file into parameters (`navigate.retry.
max_attempts`), and a stand-in node answers read_settings and read_task_specs from them.
"""

from pathlib import Path
from typing import Any

import pytest
from rclpy.impl.logging_severity import LoggingSeverity
from rclpy.parameter import Parameter, parameter_dict_from_yaml_file

from task_manager.core.admission.arbiter import DEFAULT_MAX_QUEUED
from task_manager.core.admission.options import OnConflict
from task_manager.core.admission.retry import NO_RETRY, RetryPolicy
from task_manager.core.errors import ConfigurationError
from task_manager.core.params_file import check_params_file
from task_manager.ros.parameters import NodeSettings, read_settings, read_task_specs
from task_manager.testing.process import action_task, service_task, write_params_file

FULL_ENTRIES = {
    'navigate': action_task(
        'navigation/navigate',
        '/navigate',
        resources=['base', 'arm'],
        priority=5,
        on_conflict='queue',
        timeout_sec=120,
        queue_timeout_sec=30.5,
        feedback_timeout_sec=2.0,
        retry={
            'max_attempts': 3,
            'initial_delay_sec': 1.0,
            'multiplier': 2,
            'max_delay_sec': 60.0,
            'on_error_codes': ['aborted', 'timeout'],
        },
    ),
    'photo': service_task('camera/photo', '/photo', resources=['camera']),
}


class ParametersNode:
    """What read_settings and read_task_specs ask of a node, answered from a parameters file."""

    def __init__(self, path: Path) -> None:
        check_params_file(path)
        messages = parameter_dict_from_yaml_file(str(path), target_nodes=['task_manager'])
        self.parameters = {
            name: Parameter.from_parameter_msg(message) for name, message in messages.items()
        }
        self.warnings: list[str] = []

    def has_parameter(self, name: str) -> bool:
        return name in self.parameters

    def get_parameter(self, name: str) -> Parameter[Any]:
        return self.parameters[name]

    def get_parameters_by_prefix(self, prefix: str) -> dict[str, Parameter[Any]]:
        return {
            name.removeprefix(f'{prefix}.'): parameter
            for name, parameter in self.parameters.items()
            if name.startswith(f'{prefix}.')
        }

    def get_logger(self) -> 'ParametersNode':
        return self

    def log(self, message: str, severity: LoggingSeverity) -> bool:
        """What NodeLog asks of a logger that is not rclpy's: its warnings are kept."""
        if severity is LoggingSeverity.WARN:
            self.warnings.append(message)
        return True


def node_of(tmp_path: Path, parameters: dict[str, Any]) -> Any:
    """A stand-in node holding `parameters` (with an in-memory history), as a file gives them."""
    path = write_params_file(tmp_path / 'params.yaml', {'history_path': ''} | parameters)
    return ParametersNode(path)


def settings_of(tmp_path: Path, **parameters: Any) -> NodeSettings:
    return read_settings(node_of(tmp_path, {'tasks': ['photo'], **parameters}))


def test_a_file_with_every_new_key_loads(tmp_path: Path) -> None:
    node = node_of(tmp_path, {'tasks': ['navigate', 'photo'], **FULL_ENTRIES})

    navigate, photo = read_task_specs(node, reserved_names=set())

    assert navigate.resources == ('arm', 'base')
    assert (navigate.priority, navigate.on_conflict) == (5, OnConflict.QUEUE)
    assert (navigate.timeout_sec, navigate.queue_timeout_sec) == (120.0, 30.5)
    assert navigate.feedback_timeout_sec == 2.0
    assert navigate.retry == RetryPolicy(3, 1.0, 2.0, 60.0, ('aborted', 'timeout'))
    assert photo.resources == ('camera',)
    assert photo.retry is NO_RETRY
    assert node.warnings == []


def test_a_typo_inside_retry_stops_the_node_naming_it(tmp_path: Path) -> None:
    entry = action_task('nav', '/nav', retry={'max_attempts': 2, 'initial_delay': 1.0})
    node = node_of(tmp_path, {'tasks': ['navigate'], 'navigate': entry})

    with pytest.raises(ConfigurationError) as raised:
        read_task_specs(node, reserved_names=set())

    assert str(raised.value).startswith(
        "task 'nav': navigate.retry.initial_delay is not a key of retry; its keys are "
    )


def test_unknown_keys_beside_the_new_ones_are_warned_about(tmp_path: Path) -> None:
    entry = action_task('nav', '/nav', resources=['base'], priorty=3)
    node = node_of(tmp_path, {'tasks': ['navigate'], 'navigate': entry})

    read_task_specs(node, reserved_names=set())

    assert node.warnings == ["task 'nav': ignoring unknown parameter navigate.priorty"]


def test_an_empty_resources_list_is_refused_by_the_file_check(tmp_path: Path) -> None:
    entry = service_task('photo', '/photo', resources=[])
    with pytest.raises(ConfigurationError, match=r'an empty list has no type.*leave resources out'):
        node_of(tmp_path, {'tasks': ['photo'], 'photo': entry})


def test_the_node_parameters_of_the_queue_and_the_sources(tmp_path: Path) -> None:
    photo = service_task('photo', '/photo')
    settings = settings_of(
        tmp_path, photo=photo, max_queued=7, source_priorities={'joystick': 100, 'CLOUD': 10}
    )

    assert settings.max_queued == 7
    assert settings.source_priorities == {'joystick': 100, 'CLOUD': 10}


def test_the_queue_and_the_sources_have_defaults(tmp_path: Path) -> None:
    settings = settings_of(tmp_path, photo=service_task('photo', '/photo'))

    assert settings.max_queued == DEFAULT_MAX_QUEUED == 100
    assert settings.source_priorities == {}


def test_the_middleware_watchdog_waits_30_s_by_default_and_0_turns_it_off(tmp_path: Path) -> None:
    photo = service_task('photo', '/photo')
    assert settings_of(tmp_path, photo=photo).middleware_watchdog_timeout_sec == 30.0
    off = settings_of(tmp_path, photo=photo, middleware_watchdog_timeout=0)
    assert off.middleware_watchdog_timeout_sec == 0.0


@pytest.mark.parametrize(
    ('parameters', 'message'),
    [
        ({'max_queued': -1}, "parameter 'max_queued' must be >= 0, got -1"),
        ({'max_queued': 2.5}, "parameter 'max_queued' must be int, got 2.5"),
        *(
            (
                {'middleware_watchdog_timeout': timeout},
                "parameter 'middleware_watchdog_timeout' must be 0 (off) or from 1 to 3600 s, "
                f'got {timeout}',
            )
            for timeout in (-1, 0.5, 3601)
        ),
        (
            {'source_priorities': {'joystick': 1.5}},
            "parameter 'source_priorities.joystick' must be int (the priority of source "
            "'joystick'), got 1.5",
        ),
        (
            {'source_priorities': 10},
            "parameter 'source_priorities' must be a map of source to priority, e.g. "
            '{joystick: 100, CLOUD: 10}, got 10',
        ),
    ],
)
def test_unusable_queue_and_source_parameters_are_named(
    tmp_path: Path, parameters: dict[str, Any], message: str
) -> None:
    with pytest.raises(ConfigurationError) as raised:
        settings_of(tmp_path, photo=service_task('photo', '/photo'), **parameters)
    assert str(raised.value) == message
