"""Tests of a request's effective priority: its own, else its declaration's plus its source's."""

from typing import Any

import pytest

from task_manager.core.admission.priority import (
    effective_priority,
    parse_source_priorities,
    source_priority,
)
from task_manager.core.errors import ConfigurationError

SOURCES = {'joystick': 100, 'CLOUD': 10, 'WEB': 5, 'WEB:admin': 50, 'schedule': -5}


@pytest.mark.parametrize(
    ('source', 'expected'),
    [
        ('joystick', 100),
        ('CLOUD', 10),
        ('WEB', 5),
        ('WEB:alice', 5),
        ('WEB:admin', 50),
        ('WEB:alice:x', 5),
        ('schedule', -5),
        ('cloud', 0),
        ('CLOUD-2', 0),
        ('', 0),
        (':WEB', 0),
        ('joystick2', 0),
    ],
)
def test_a_source_is_matched_exactly_else_by_its_part_before_the_colon(
    source: str, expected: int
) -> None:
    assert source_priority(source, SOURCES) == expected


def test_the_requests_own_priority_wins() -> None:
    assert effective_priority(3, 'joystick', SOURCES, requested=1) == 1
    assert effective_priority(3, 'joystick', SOURCES, requested=0) == 0
    assert effective_priority(3, 'joystick', SOURCES, requested=-2) == -2


@pytest.mark.parametrize(
    ('spec_priority', 'source', 'expected'),
    [(0, 'CLI', 0), (5, 'CLI', 5), (5, 'joystick', 105), (2, 'WEB:bob', 7), (0, 'schedule', -5)],
)
def test_without_its_own_the_declared_and_the_sources_priority_add_up(
    spec_priority: int, source: str, expected: int
) -> None:
    assert effective_priority(spec_priority, source, SOURCES, requested=None) == expected


def test_no_source_priorities_leave_the_declared_one() -> None:
    assert effective_priority(4, 'joystick', {}, None) == 4


def test_source_priorities_are_ints() -> None:
    assert parse_source_priorities({'joystick': 100, 'CLOUD': -1}) == {'joystick': 100, 'CLOUD': -1}
    assert parse_source_priorities({}) == {}


@pytest.mark.parametrize('value', [1.5, True, '10', None, [1]])
def test_a_source_priority_that_is_no_int_is_named(value: Any) -> None:
    with pytest.raises(ConfigurationError) as raised:
        parse_source_priorities({'joystick': 100, 'CLOUD': value})
    assert str(raised.value) == (
        f"parameter 'source_priorities.CLOUD' must be int (the priority of source 'CLOUD'), "
        f'got {value!r}'
    )
