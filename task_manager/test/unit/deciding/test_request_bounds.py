"""Every number a request carries is bounded, and a refusal names the field and the bound."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from task_manager.core import bounds
from task_manager.core.admission.options import RequestOptions

TIMEOUTS = ('timeout_sec', 'queue_timeout_sec', 'feedback_timeout_sec')


@pytest.mark.parametrize('name', TIMEOUTS)
@pytest.mark.parametrize('value', [-1.0, 604_800.001, 1e10, 1e300])
def test_a_timeout_outside_zero_to_a_week_is_refused_naming_it(name: str, value: float) -> None:
    assert RequestOptions.from_dict({name: value}).problem() == (
        f'{name} must be from 0 to 604800 s, got {value!r}'
    )


@pytest.mark.parametrize('name', TIMEOUTS)
@pytest.mark.parametrize('value', [math.inf, -math.inf, math.nan])
def test_a_timeout_that_is_not_finite_is_refused(name: str, value: float) -> None:
    assert RequestOptions.from_dict({name: value}).problem() == (
        f'{name} must be a finite number, got {value!r}'
    )


@pytest.mark.parametrize('priority', [2**31, -(2**31) - 1, 10**30])
def test_a_priority_outside_int32_is_refused(priority: int) -> None:
    assert RequestOptions(priority=priority).problem() == (
        f'priority must be from -2147483648 to 2147483647, got {priority}'
    )


@given(
    st.one_of(st.none(), st.floats(0, 604_800)),
    st.one_of(st.none(), st.integers(-(2**31), 2**31 - 1)),
)
def test_options_within_the_bounds_are_usable(timeout: float | None, priority: int | None) -> None:
    assert RequestOptions(priority=priority, timeout_sec=timeout).problem() == ''


@pytest.mark.parametrize('value', [True, '5', None, [1]])
def test_a_bound_refuses_what_is_not_a_number(value: object) -> None:
    assert bounds.SECONDS.problem('delay', value).startswith('delay must be a number, got ')


def test_an_id_given_twice_is_named() -> None:
    assert bounds.duplicate_problem('task_ids', ['a', 'b', 'a']) == (
        "task_ids names 'a' more than once; each id at most once"
    )
    assert bounds.duplicate_problem('task_ids', ['a', 'b']) == ''


def test_echoed_text_is_cut_with_a_count_of_what_was_left_out() -> None:
    cut = bounds.cut_text('x' * 1000)
    assert cut == 'x' * bounds.ECHO_MAX_CHARACTERS + '… (800 more characters)'
    assert bounds.cut_text('short') == 'short'
