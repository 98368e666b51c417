"""Tests of a declaration's retry policy: which ends are retried, and the backoff between."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from task_manager.core.admission.retry import NO_RETRY, SERVER_ERROR, RetryPolicy
from task_manager.core.status import ErrorCode

FAST = settings(max_examples=100, deadline=None)


def test_no_retry_is_one_attempt() -> None:
    assert NO_RETRY.max_attempts == 1
    assert not NO_RETRY.retries(1, ErrorCode.NONE)
    assert not NO_RETRY.retries(1, ErrorCode.TIMEOUT)


def test_retries_until_the_attempts_run_out() -> None:
    policy = RetryPolicy(max_attempts=3)
    assert [policy.retries(attempt, ErrorCode.NONE) for attempt in (1, 2, 3, 4)] == [
        True,
        True,
        False,
        False,
    ]


def test_no_error_codes_retries_any_error() -> None:
    policy = RetryPolicy(max_attempts=2)
    for code in (ErrorCode.NONE, ErrorCode.TIMEOUT, ErrorCode.TASK_START_FAILED):
        assert policy.retries(1, code)


@pytest.mark.parametrize(
    ('on_error_codes', 'code', 'expected'),
    [
        ((SERVER_ERROR,), ErrorCode.NONE, True),
        ((SERVER_ERROR,), ErrorCode.TIMEOUT, False),
        (('timeout',), ErrorCode.TIMEOUT, True),
        (('timeout',), ErrorCode.NONE, False),
        (('timeout', 'task_start_failed'), ErrorCode.TASK_START_FAILED, True),
        (('timeout', 'task_start_failed'), ErrorCode.NONE, False),
    ],
)
def test_error_codes_choose_the_ends_worth_another_attempt(
    on_error_codes: tuple[str, ...], code: ErrorCode, expected: bool
) -> None:
    """A server's own ERROR has no error code: SERVER_ERROR ('aborted') names it."""
    assert RetryPolicy(max_attempts=5, on_error_codes=on_error_codes).retries(1, code) is expected


def test_delays_grow_by_the_multiplier_up_to_the_cap() -> None:
    policy = RetryPolicy(max_attempts=9, initial_delay_sec=1.0, multiplier=2.0, max_delay_sec=10.0)
    delays = [policy.delay_sec(attempt) for attempt in range(1, 7)]
    assert delays == [1.0, 2.0, 4.0, 8.0, 10.0, 10.0]


def test_a_multiplier_of_one_waits_the_same_each_time() -> None:
    policy = RetryPolicy(max_attempts=4, initial_delay_sec=0.5, multiplier=1.0)
    assert {policy.delay_sec(attempt) for attempt in range(1, 50)} == {0.5}


def test_a_cap_below_the_first_delay_caps_it() -> None:
    assert RetryPolicy(initial_delay_sec=5.0, max_delay_sec=2.0).delay_sec(1) == 2.0


def test_no_initial_delay_never_waits() -> None:
    policy = RetryPolicy(max_attempts=10**6, initial_delay_sec=0.0, multiplier=10.0)
    assert policy.delay_sec(1) == policy.delay_sec(10**6) == 0.0


def test_a_huge_attempt_number_waits_the_cap_without_overflow() -> None:
    policy = RetryPolicy(max_attempts=10**6, initial_delay_sec=1.0, multiplier=2.0)
    assert policy.delay_sec(10**5) == policy.max_delay_sec == 60.0
    assert RetryPolicy(multiplier=2).delay_sec(5000) == 60.0  # an int power, too big for a float


@pytest.mark.parametrize(
    ('policy', 'problem'),
    [
        (RetryPolicy(), ''),
        (RetryPolicy(5, 0.0, 1.0, 0.0, ('aborted', 'timeout')), ''),
        (RetryPolicy(max_attempts=0), 'max_attempts must be >= 1 (1: no retry), got 0'),
        (RetryPolicy(initial_delay_sec=-1.0), 'initial_delay_sec must be from 0 to 604800 s'),
        (RetryPolicy(initial_delay_sec=1e9), 'initial_delay_sec must be from 0 to 604800 s'),
        (RetryPolicy(max_delay_sec=float('nan')), 'max_delay_sec must be a finite number'),
        (RetryPolicy(multiplier=0.9), 'multiplier must be a finite number >= 1, got 0.9'),
        (RetryPolicy(multiplier=float('inf')), 'multiplier must be a finite number >= 1'),
        (RetryPolicy(on_error_codes=('queue_full',)), 'on_error_codes must name some of'),
    ],
)
def test_problem_names_the_unusable_field(policy: RetryPolicy, problem: str) -> None:
    if problem:
        assert policy.problem().startswith(problem)
    else:
        assert policy.problem() == ''


@FAST
@given(
    initial=st.floats(0, 1e3),
    multiplier=st.floats(1, 10),
    cap=st.floats(0, 1e4),
    attempt=st.integers(1, 10_000),
)
def test_delays_never_shrink_and_never_pass_the_cap(
    initial: float, multiplier: float, cap: float, attempt: int
) -> None:
    policy = RetryPolicy(10_001, initial, multiplier, cap)
    assert 0 <= policy.delay_sec(attempt) <= policy.delay_sec(attempt + 1) <= cap
