"""Tests of a task entry's keys that decide what runs: resources, priority, on_conflict,
timeouts and retry (issue 29), and of the entry as ROS parameters give it (no ROS needed)."""

import math
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from task_manager.core.admission.options import OnConflict
from task_manager.core.admission.retry import RETRYABLE_ERROR_CODES, SERVER_ERROR, RetryPolicy
from task_manager.core.errors import ConfigurationError
from task_manager.core.task_spec import (
    RETRY_KEYS,
    TIMEOUT_KEYS,
    TaskSpec,
    nested_entry,
    parse_task_spec,
    unknown_keys,
)

FAST = settings(max_examples=60, deadline=None)
ACTION = {'task_name': 'fib', 'topic': '/fibonacci', 'msg_interface': 'test_msgs.action.Fibonacci'}
SERVICE = {'task_name': 'trigger', 'topic': '/trigger', 'msg_interface': 'std_srvs.srv.Trigger'}


def parse(**keys: Any) -> TaskSpec:
    """The action task 'fib' of entry key 'fib_key', with `keys` added."""
    return parse_task_spec('fib_key', ACTION | keys)


def refusal(**keys: Any) -> str:
    """The message that refuses the action task 'fib' with `keys` added."""
    with pytest.raises(ConfigurationError) as raised:
        parse(**keys)
    return str(raised.value)


# ---- resources -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ('value', 'expected'),
    [
        (['base'], ('base',)),
        (['camera', 'arm'], ('arm', 'camera')),
        (
            ('arm/left', 'lidar.front', 'gripper-2', 'Base_1'),
            ('Base_1', 'arm/left', 'gripper-2', 'lidar.front'),
        ),
        ([], ()),
    ],
)
def test_resources_are_kept_sorted(value: Any, expected: tuple[str, ...]) -> None:
    assert parse(resources=value).resources == expected


@pytest.mark.parametrize('value', ['base', 3, True, [1, 2], ['base', 7], {'base': 1}])
def test_resources_must_be_a_list_of_strings(value: Any) -> None:
    message = refusal(resources=value)
    assert message == (
        f"task 'fib': fib_key.resources must be a list of strings, e.g. [base], got {value!r}"
    )


@pytest.mark.parametrize('name', ['', ' base', 'base arm', 'café', 'arm:left', 'a\nb', 'x*'])
def test_resource_names_are_letters_digits_and_a_few_signs(name: str) -> None:
    message = refusal(resources=['base', name])
    assert message == (
        f"task 'fib': fib_key.resources: {name!r} is not a resource name "
        '(one or more letters, digits and _ . / -)'
    )


@pytest.mark.parametrize('name', ['@blocking', '@task:fib', '@'])
def test_resource_names_starting_with_at_are_reserved(name: str) -> None:
    message = refusal(resources=[name])
    assert message.startswith(f"task 'fib': fib_key.resources: {name!r} starts with '@'")
    assert 'reserved for the implicit resources' in message


def test_a_resource_named_twice_is_refused() -> None:
    message = refusal(resources=['base', 'arm', 'base', 'arm', 'camera'])
    assert message == "task 'fib': fib_key.resources names 'arm', 'base' more than once"


# ---- priority and on_conflict ----------------------------------------------------------------


@pytest.mark.parametrize('value', [0, 5, -3, 10**12])
def test_priority_is_any_int(value: int) -> None:
    assert parse(priority=value).priority == value


@pytest.mark.parametrize('value', [True, 1.0, '5', None])
def test_priority_must_be_an_int(value: Any) -> None:
    assert refusal(priority=value) == f"task 'fib': fib_key.priority must be int, got {value!r}"


@pytest.mark.parametrize(
    ('text', 'expected'),
    [
        ('preempt', OnConflict.PREEMPT),
        ('queue', OnConflict.QUEUE),
        ('reject', OnConflict.REJECT),
        (' Queue ', OnConflict.QUEUE),
        ('REJECT', OnConflict.REJECT),
    ],
)
def test_on_conflict_is_one_of_three_in_any_case(text: str, expected: OnConflict) -> None:
    assert parse(on_conflict=text).on_conflict is expected


@pytest.mark.parametrize(('value', 'words'), [('wait', "got 'wait'"), ('', "got ''")])
def test_on_conflict_names_the_choices(value: str, words: str) -> None:
    message = refusal(on_conflict=value)
    assert (
        message == f"task 'fib': fib_key.on_conflict must be one of preempt, queue, reject, {words}"
    )


def test_on_conflict_must_be_a_string() -> None:
    assert refusal(on_conflict=1) == "task 'fib': fib_key.on_conflict must be str, got 1"


# ---- timeouts --------------------------------------------------------------------------------


@pytest.mark.parametrize('name', TIMEOUT_KEYS)
@pytest.mark.parametrize(
    ('value', 'expected'), [(0, 0.0), (3, 3.0), (0.5, 0.5), (604_800, 604_800.0)]
)
def test_timeouts_accept_ints_and_floats(name: str, value: float, expected: float) -> None:
    spec = parse(**{name: value})
    assert getattr(spec, name) == expected
    assert type(getattr(spec, name)) is float


@pytest.mark.parametrize('name', TIMEOUT_KEYS)
@pytest.mark.parametrize('value', [-1, -0.5, 604_800.5, 1e10])
def test_timeouts_must_be_from_zero_to_a_week(name: str, value: float) -> None:
    assert refusal(**{name: value}) == (
        f"task 'fib': fib_key.{name} must be from 0 to 604800 s, got {value!r} (0: none)"
    )


@pytest.mark.parametrize('name', TIMEOUT_KEYS)
@pytest.mark.parametrize('value', [math.inf, math.nan])
def test_timeouts_must_be_finite(name: str, value: float) -> None:
    assert refusal(**{name: value}) == (
        f"task 'fib': fib_key.{name} must be a finite number, got {value!r} (0: none)"
    )


@pytest.mark.parametrize('name', TIMEOUT_KEYS)
@pytest.mark.parametrize('value', [True, '5', None, [1]])
def test_timeouts_must_be_numbers(name: str, value: Any) -> None:
    assert refusal(**{name: value}) == (
        f"task 'fib': fib_key.{name} must be int or float, got {value!r}"
    )


def test_timeouts_of_a_service_task() -> None:
    spec = parse_task_spec('t', SERVICE | {'timeout_sec': 2, 'queue_timeout_sec': 3})
    assert (spec.timeout_sec, spec.queue_timeout_sec) == (2.0, 3.0)
    assert parse_task_spec('t', SERVICE | {'feedback_timeout_sec': 0}).feedback_timeout_sec == 0


def test_a_feedback_timeout_is_refused_for_a_service_task() -> None:
    with pytest.raises(ConfigurationError) as raised:
        parse_task_spec('t', SERVICE | {'feedback_timeout_sec': 1.5})
    assert str(raised.value) == (
        "task 'trigger': feedback_timeout_sec is only for action tasks (a service sends no "
        'feedback), and std_srvs/srv/Trigger is a service'
    )


# ---- retry -----------------------------------------------------------------------------------


def test_a_full_retry_map_becomes_the_policy() -> None:
    retry = {
        'max_attempts': 3,
        'initial_delay_sec': 1,
        'multiplier': 1.5,
        'max_delay_sec': 60.0,
        'on_error_codes': ['Aborted', ' timeout', 'task_start_failed'],
    }
    policy = parse(retry=retry).retry
    assert policy == RetryPolicy(3, 1.0, 1.5, 60.0, ('aborted', 'timeout', 'task_start_failed'))
    assert type(policy.initial_delay_sec) is float


def test_a_retry_map_with_max_attempts_only_takes_the_default_backoff() -> None:
    assert parse(retry={'max_attempts': 4}).retry == RetryPolicy(max_attempts=4)


def test_on_error_codes_may_name_each_end_of_a_started_task() -> None:
    policy = parse(retry={'max_attempts': 2, 'on_error_codes': list(RETRYABLE_ERROR_CODES)}).retry
    assert policy.on_error_codes == RETRYABLE_ERROR_CODES
    assert SERVER_ERROR in RETRYABLE_ERROR_CODES


@pytest.mark.parametrize(
    ('retry', 'words'),
    [
        (3, 'fib_key.retry must be a map of max_attempts, initial_delay_sec, multiplier, '
            'max_delay_sec, on_error_codes, got 3'),
        ({'max_attempts': 2, 'max_atempts': 3}, 'fib_key.retry.max_atempts is not a key of retry'),
        ({'initial_delay_sec': 2}, 'fib_key.retry.max_attempts is missing'),
        ({'max_attempts': 0}, 'fib_key.retry.max_attempts must be >= 1 (1: no retry), got 0'),
        ({'max_attempts': 2.0}, 'fib_key.retry.max_attempts must be int, got 2.0'),
        ({'max_attempts': True}, 'fib_key.retry.max_attempts must be int, got True'),
        ({'max_attempts': 2, 'initial_delay_sec': -1},
         'fib_key.retry.initial_delay_sec must be from 0 to 604800 s, got -1.0'),
        ({'max_attempts': 2, 'max_delay_sec': math.inf},
         'fib_key.retry.max_delay_sec must be a finite number, got inf'),
        ({'max_attempts': 2, 'max_delay_sec': '9'},
         "fib_key.retry.max_delay_sec must be int or float, got '9'"),
        ({'max_attempts': 2, 'multiplier': 0.5},
         'fib_key.retry.multiplier must be a finite number >= 1, got 0.5'),
        ({'max_attempts': 2, 'multiplier': math.nan},
         'fib_key.retry.multiplier must be a finite number >= 1, got nan'),
        ({'max_attempts': 2, 'on_error_codes': 'timeout'},
         "fib_key.retry.on_error_codes must be a list of strings, e.g. [aborted], got 'timeout'"),
        ({'max_attempts': 2, 'on_error_codes': ['unknown_task']},
         'fib_key.retry.on_error_codes must name some of aborted, task_start_failed, timeout, '
         "got 'unknown_task'"),
        ({'max_attempts': 2, 'on_error_codes': ['timeout', 'resource_busy']},
         "got 'resource_busy'"),
    ],
)  # fmt: skip
def test_an_unusable_retry_map_is_named(retry: Any, words: str) -> None:
    message = refusal(retry=retry)
    assert message.startswith("task 'fib': fib_key.retry")
    assert words in message


def test_every_field_of_the_retry_policy_is_a_key_of_retry() -> None:
    assert set(RETRY_KEYS) == set(RetryPolicy.__dataclass_fields__)


# ---- the entry as ROS parameters give it -----------------------------------------------------


def test_nested_entry_gathers_the_retry_map() -> None:
    flat = {
        'task_name': 'fib',
        'retry.max_attempts': 3,
        'retry.on_error_codes': ['timeout'],
        'resources': ['base'],
    }
    assert nested_entry(flat) == {
        'task_name': 'fib',
        'retry': {'max_attempts': 3, 'on_error_codes': ['timeout']},
        'resources': ['base'],
    }


def test_nested_entry_leaves_other_dotted_keys_flat() -> None:
    flat = {'retyr.max_attempts': 3, 'a.b.c': 1}
    assert nested_entry(flat) == flat
    assert unknown_keys(nested_entry(flat)) == ['a.b.c', 'retyr.max_attempts']


def test_a_retry_value_beside_retry_keys_is_refused_as_no_map() -> None:
    entry = nested_entry(ACTION | {'retry': 3, 'retry.max_attempts': 2})
    with pytest.raises(ConfigurationError, match=r'fib_key\.retry must be a map'):
        parse_task_spec('fib_key', entry)


def test_a_typo_inside_a_flat_retry_map_is_refused_by_name() -> None:
    entry = nested_entry(ACTION | {'retry.max_attempts': 2, 'retry.multiplyer': 2.0})
    with pytest.raises(ConfigurationError) as raised:
        parse_task_spec('fib_key', entry)
    assert str(raised.value).startswith(
        "task 'fib': fib_key.retry.multiplyer is not a key of retry; its keys are max_attempts, "
    )


# ---- properties ------------------------------------------------------------------------------

resource_names = st.from_regex(r'[A-Za-z0-9_./-]{1,12}', fullmatch=True)
seconds = st.integers(0, 604_800) | st.floats(0, 604_800, allow_nan=False)
retry_maps = st.fixed_dictionaries(
    {'max_attempts': st.integers(1, 100)},
    optional={
        'initial_delay_sec': seconds,
        'multiplier': st.floats(1, 10),
        'max_delay_sec': seconds,
        'on_error_codes': st.lists(st.sampled_from(RETRYABLE_ERROR_CODES), min_size=1),
    },
)


@FAST
@given(
    resources=st.lists(resource_names, unique=True, max_size=5),
    priority=st.integers(-(2**63), 2**63 - 1),
    on_conflict=st.sampled_from(list(OnConflict)),
    timeouts=st.fixed_dictionaries({}, optional=dict.fromkeys(TIMEOUT_KEYS, seconds)),
    retry=st.none() | retry_maps,
)
def test_valid_admission_keys_round_trip_into_the_spec(
    resources: list[str],
    priority: int,
    on_conflict: OnConflict,
    timeouts: dict[str, float],
    retry: dict[str, Any] | None,
) -> None:
    keys = {'resources': resources, 'priority': priority, 'on_conflict': on_conflict.value}
    keys |= timeouts | ({'retry': retry} if retry is not None else {})
    spec = parse(**keys)
    assert spec.resources == tuple(sorted(resources))
    assert (spec.priority, spec.on_conflict) == (priority, on_conflict)
    for name in TIMEOUT_KEYS:
        assert getattr(spec, name) == float(timeouts.get(name, 0))
    assert spec.retry.max_attempts == (retry or {}).get('max_attempts', 1)
    assert unknown_keys(ACTION | keys) == []
