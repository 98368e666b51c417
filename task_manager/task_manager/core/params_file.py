"""Checks of a parameters file that ROS itself would refuse with a traceback, done first.

rcl and rclpy reject lists that are empty or mix types and empty mappings, and read
subnormal floats as strings; they say so in several lines or a traceback. Checking the
YAML first gives one line that names the parameter.
"""

import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import yaml

from task_manager.core.errors import ConfigurationError

# key: last part of a parameter's name, value: what to write instead of an empty list
EMPTY_LIST_HINTS = {
    'resources': 'leave resources out for a task that holds none',
    'on_error_codes': 'leave on_error_codes out to retry after any error',
}


def params_files(arguments: list[str]) -> list[Path]:
    """The files given with `--params-file` in a command line."""
    return [
        Path(arguments[i + 1])
        for i, argument in enumerate(arguments[:-1])
        if argument == '--params-file'
    ]


def check_params_file(path: Path) -> None:
    """Raise ConfigurationError for the first value ROS parameters cannot hold."""
    try:
        content = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as error:
        raise ConfigurationError(f'cannot read parameters file {path}: {error}') from error
    for name, value in _leaves(content, ''):
        problem = _problem(value)
        hint = EMPTY_LIST_HINTS.get(name.rsplit('.', 1)[-1]) if value == [] else None
        if hint:
            problem = f'{problem}; {hint}'
        if problem:
            raise ConfigurationError(f'parameter {name!r} in {path}: {problem}')


def _leaves(content: Any, prefix: str) -> Iterator[tuple[str, Any]]:
    if isinstance(content, dict) and content:
        for key, value in content.items():
            yield from _leaves(value, f'{prefix}.{key}' if prefix else str(key))
    else:
        yield prefix, content


def _is_subnormal(value: Any) -> bool:
    return isinstance(value, float) and 0.0 < abs(value) < sys.float_info.min


def _problem(value: Any) -> str:
    if value == {}:
        return 'an empty mapping is no value; give the entry its keys or remove it'
    if _is_subnormal(value) or (isinstance(value, list) and any(map(_is_subnormal, value))):
        return 'a float too small for ROS parameters (subnormal)'
    if not isinstance(value, list):
        return ''
    if not value:
        return 'an empty list has no type; ROS parameters need at least one element'
    if len({type(v) for v in value}) > 1:
        kinds = ', '.join(sorted({type(v).__name__ for v in value}))
        return f'a list must hold one type of value, this one mixes {kinds}'
    return ''
