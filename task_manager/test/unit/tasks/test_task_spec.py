"""Tests of task declarations: parameter entries parsed into TaskSpecs (no ROS needed)."""

import math
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from task_manager.core.admission.options import OnConflict
from task_manager.core.admission.retry import NO_RETRY
from task_manager.core.errors import ConfigurationError
from task_manager.core.task_spec import (
    DEFAULT_CANCEL_TIMEOUT_SEC,
    RETRY_KEYS,
    InterfaceName,
    TaskKind,
    TaskSpec,
    parse_interface_name,
    parse_task_spec,
    parse_task_specs,
    unknown_keys,
)

FAST = settings(max_examples=60, deadline=None)
DROP: Any = object()
"""An `entry()` override value that removes the key from the entry."""
BOOL_OPTIONS = ('blocking', 'cancel_on_stop', 'reentrant', 'cancel_reported_as_success')
REQUIRED = ('task_name', 'topic', 'msg_interface')


def entry(**overrides: Any) -> dict[str, Any]:
    """A valid action task entry named 'fib', with `overrides` applied (DROP removes a key)."""
    values: dict[str, Any] = {
        'task_name': 'fib',
        'topic': '/fibonacci',
        'msg_interface': 'test_msgs.action.Fibonacci',
    }
    values.update(overrides)
    return {key: value for key, value in values.items() if value is not DROP}


def service_entry(**overrides: Any) -> dict[str, Any]:
    """A valid service task entry named 'trigger', with `overrides` applied."""
    return entry(
        **{'task_name': 'trigger', 'topic': '/trigger', 'msg_interface': 'std_srvs.srv.Trigger'}
        | overrides
    )


def parse(**overrides: Any) -> TaskSpec:
    return parse_task_spec('fib_key', entry(**overrides))


# ---- msg_interface ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ('text', 'expected'),
    [
        ('test_msgs.action.Fibonacci', InterfaceName('test_msgs', TaskKind.ACTION, 'Fibonacci')),
        ('test_msgs/action/Fibonacci', InterfaceName('test_msgs', TaskKind.ACTION, 'Fibonacci')),
        ('std_srvs.srv.Trigger', InterfaceName('std_srvs', TaskKind.SERVICE, 'Trigger')),
        ('std_srvs/srv/Trigger', InterfaceName('std_srvs', TaskKind.SERVICE, 'Trigger')),
        ('  std_srvs/srv/Trigger\n', InterfaceName('std_srvs', TaskKind.SERVICE, 'Trigger')),
    ],
)
def test_parse_interface_name_accepts_dotted_and_slashed_forms(
    text: str, expected: InterfaceName
) -> None:
    interface = parse_interface_name(text)
    assert interface == expected
    assert str(interface) == f'{expected.package}/{expected.kind.value}/{expected.name}'


@pytest.mark.parametrize(
    ('msg_interface', 'kind'),
    [
        ('test_msgs.action.Fibonacci', TaskKind.ACTION),
        ('test_msgs/action/Fibonacci', TaskKind.ACTION),
        ('std_srvs.srv.Trigger', TaskKind.SERVICE),
        ('std_srvs/srv/Trigger', TaskKind.SERVICE),
    ],
)
def test_task_kind_follows_msg_interface(msg_interface: str, kind: TaskKind) -> None:
    spec = parse(msg_interface=msg_interface)
    assert spec.kind is kind
    assert spec.interface.kind is kind


@pytest.mark.parametrize(
    'text',
    [
        '',
        'Fibonacci',
        'test_msgs/Fibonacci',
        'test_msgs.msg.Fibonacci',
        'test_msgs/msg/Fibonacci',
        'test_msgs/action/',
        '/action/Fibonacci',
        'test_msgs/action/Fibonacci/Goal',
        'test_msgs::action::Fibonacci',
        'test msgs/action/Fibonacci',
        'test_msgs/Action/Fibonacci',
    ],
)
def test_parse_interface_name_rejects_malformed_names(text: str) -> None:
    with pytest.raises(ConfigurationError) as raised:
        parse_interface_name(text)
    message = str(raised.value)
    assert repr(text) in message
    assert 'package.action.Name' in message
    assert 'package/srv/Name' in message


def test_malformed_msg_interface_in_an_entry_names_the_task() -> None:
    with pytest.raises(ConfigurationError, match=r"^task 'fib': msg_interface 'test_msgs/msg/X'"):
        parse(msg_interface='test_msgs/msg/X')


# ---- optional keys ---------------------------------------------------------------------------


def test_omitted_optional_keys_take_their_defaults() -> None:
    spec = parse_task_spec('fib_key', entry())
    assert spec == TaskSpec(
        task_name='fib',
        topic='/fibonacci',
        interface=InterfaceName('test_msgs', TaskKind.ACTION, 'Fibonacci'),
    )
    assert spec.blocking is False
    assert spec.cancel_on_stop is False
    assert spec.reentrant is False
    assert spec.cancel_reported_as_success is False
    assert spec.service_success_field == ''
    assert spec.cancel_timeout_sec == 5.0 == DEFAULT_CANCEL_TIMEOUT_SEC
    assert isinstance(spec.cancel_timeout_sec, float)
    assert spec.parameter_key == 'fib_key'
    assert spec.resources == ()
    assert spec.priority == 0
    assert spec.on_conflict is OnConflict.PREEMPT
    assert spec.timeout_sec == spec.queue_timeout_sec == spec.feedback_timeout_sec == 0.0
    assert spec.retry is NO_RETRY


def test_required_strings_are_stripped() -> None:
    spec = parse(task_name='  fib ', topic=' /fibonacci\t')
    assert spec.task_name == 'fib'
    assert spec.topic == '/fibonacci'


@pytest.mark.parametrize(('value', 'expected'), [(1, 1.0), (0, 0.0), (30, 30.0), (0.25, 0.25)])
def test_cancel_timeout_accepts_int_and_float(value: float, expected: float) -> None:
    spec = parse(cancel_timeout=value)
    assert spec.cancel_timeout_sec == expected
    assert type(spec.cancel_timeout_sec) is float


@pytest.mark.parametrize('value', [True, False, '5', '5.0', None, [5]])
def test_cancel_timeout_rejects_non_numbers(value: Any) -> None:
    with pytest.raises(ConfigurationError) as raised:
        parse(cancel_timeout=value)
    message = str(raised.value)
    assert message.startswith("task 'fib': fib_key.cancel_timeout must be int or float")
    assert repr(value) in message


@pytest.mark.parametrize('value', [-1, -0.001, -math.inf, 604_801, 1e300])
def test_cancel_timeout_rejects_values_outside_zero_to_a_week(value: float) -> None:
    with pytest.raises(
        ConfigurationError,
        match=r"^task 'fib': fib_key\.cancel_timeout must be (from 0 to 604800 s|a finite number)",
    ):
        parse(cancel_timeout=value)


def test_cancel_timeout_rejects_nan() -> None:
    with pytest.raises(ConfigurationError, match='cancel_timeout'):
        parse(cancel_timeout=math.nan)


@pytest.mark.parametrize('option', BOOL_OPTIONS)
@pytest.mark.parametrize('value', ['true', 'false', 1, 0, 1.0, None, ''])
def test_bool_options_reject_non_bools(option: str, value: Any) -> None:
    with pytest.raises(ConfigurationError) as raised:
        parse(**{option: value})
    message = str(raised.value)
    assert message.startswith(f"task 'fib': fib_key.{option} must be bool")
    assert repr(value) in message


@pytest.mark.parametrize('option', BOOL_OPTIONS)
def test_bool_options_set_their_field(option: str) -> None:
    spec = parse(**{option: True})
    assert getattr(spec, option) is True
    others = [getattr(spec, other) for other in BOOL_OPTIONS if other != option]
    assert others == [False, False, False]


@pytest.mark.parametrize('value', [True, 1, None, ['success']])
def test_service_success_field_must_be_a_string(value: Any) -> None:
    with pytest.raises(
        ConfigurationError, match=r"^task 'trigger': trigger\.service_success_field must be str"
    ):
        parse_task_spec('trigger', service_entry(service_success_field=value))


def test_service_success_field_is_accepted_on_a_service_task() -> None:
    spec = parse_task_spec('trigger', service_entry(service_success_field='success'))
    assert spec.kind is TaskKind.SERVICE
    assert spec.service_success_field == 'success'


@pytest.mark.parametrize('msg_interface', ['test_msgs.action.Fibonacci', 'test_msgs/action/Fib'])
def test_service_success_field_is_rejected_on_an_action_task(msg_interface: str) -> None:
    with pytest.raises(ConfigurationError) as raised:
        parse(msg_interface=msg_interface, service_success_field='success')
    message = str(raised.value)
    assert message.startswith("task 'fib': service_success_field is only for service tasks")
    assert 'is an action' in message


@pytest.mark.parametrize(
    ('value', 'mode'), [('none', 'none'), ('restart', 'restart'), (' Restart ', 'restart')]
)
def test_pause_is_none_by_default_or_restart(value: str, mode: str) -> None:
    assert parse().pause == 'none'
    assert parse(pause=value).pause == mode


@pytest.mark.parametrize(
    ('overrides', 'words'),
    [
        (
            {'pause': 'between_subtasks'},
            "fib_key.pause must be one of none, restart, got 'between_subtasks'",
        ),
        ({'pause': 'later'}, "fib_key.pause must be one of none, restart, got 'later'"),
        ({'pause': True}, 'fib_key.pause must be str, got True'),
        ({'pause': 'restart', 'cancel_reported_as_success': True}, 'use one of them'),
    ],
)
def test_unusable_pause_settings_are_named(overrides: dict[str, Any], words: str) -> None:
    with pytest.raises(ConfigurationError, match=r"^task 'fib': ") as raised:
        parse(**overrides)
    assert words in str(raised.value)


def test_pause_restart_is_refused_for_a_service_task() -> None:
    with pytest.raises(ConfigurationError, match='pause: restart is only for action tasks'):
        parse_task_spec('trigger', service_entry(pause='restart'))


# ---- required keys ---------------------------------------------------------------------------


@pytest.mark.parametrize('key', REQUIRED)
def test_missing_required_key_names_the_task_and_the_key(key: str) -> None:
    # without a task_name, the task is named by its entry key
    label = 'fib_key' if key == 'task_name' else 'fib'
    with pytest.raises(ConfigurationError) as raised:
        parse(**{key: DROP})
    assert str(raised.value) == f"task '{label}': fib_key.{key} is missing"


@pytest.mark.parametrize('key', REQUIRED)
@pytest.mark.parametrize('value', ['', '   ', 5, True, ['x']])
def test_empty_or_non_string_required_key_names_the_task_and_the_key(key: str, value: Any) -> None:
    with pytest.raises(ConfigurationError) as raised:
        parse(**{key: value})
    message = str(raised.value)
    assert f'fib_key.{key} must be a non-empty string, got {value!r}' in message
    if key != 'task_name':
        assert message.startswith("task 'fib': ")


# ---- parse_task_specs ------------------------------------------------------------------------


def test_parse_task_specs_parses_listed_entries_in_order() -> None:
    entries = {'b': service_entry(), 'a': entry(blocking=True)}
    specs = parse_task_specs(['b', 'a'], entries, reserved_names={'system/stop'})
    assert [spec.task_name for spec in specs] == ['trigger', 'fib']
    assert [spec.parameter_key for spec in specs] == ['b', 'a']
    assert specs[1].blocking is True


def test_parse_task_specs_accepts_an_empty_list() -> None:
    assert parse_task_specs([], {}, reserved_names=set()) == []


def test_parse_task_specs_rejects_duplicate_task_names_naming_both_entries() -> None:
    entries = {'first': entry(), 'other': service_entry(task_name='fib')}
    with pytest.raises(ConfigurationError) as raised:
        parse_task_specs(['first', 'other'], entries, reserved_names=set())
    assert str(raised.value) == "task 'fib': declared twice (entries 'first' and 'other')"


def test_parse_task_specs_compares_task_names_after_stripping() -> None:
    entries = {'first': entry(), 'other': entry(task_name=' fib ')}
    with pytest.raises(ConfigurationError, match='declared twice'):
        parse_task_specs(['first', 'other'], entries, reserved_names=set())


@pytest.mark.parametrize('name', ['system/stop', 'system/mission'])
def test_parse_task_specs_rejects_reserved_names(name: str) -> None:
    entries = {'ok': service_entry(), 'mine': entry(task_name=name)}
    with pytest.raises(ConfigurationError) as raised:
        parse_task_specs(['ok', 'mine'], entries, reserved_names={'system/stop', 'system/mission'})
    assert str(raised.value) == f"task '{name}': the name is reserved for a system task"


def test_parse_task_specs_rejects_a_listed_key_without_an_entry() -> None:
    with pytest.raises(ConfigurationError) as raised:
        parse_task_specs(['fib_key', 'ghost'], {'fib_key': entry()}, reserved_names=set())
    message = str(raised.value)
    assert message.startswith("task 'ghost': listed in 'tasks' but has no parameters")
    assert 'ghost.task_name' in message


@pytest.mark.parametrize('task_keys', ['fib_key', None, 3, {'fib_key': 1}, ['fib_key', 7]])
def test_parse_task_specs_rejects_a_tasks_parameter_that_is_not_a_list_of_strings(
    task_keys: Any,
) -> None:
    with pytest.raises(ConfigurationError) as raised:
        parse_task_specs(task_keys, {'fib_key': entry()}, reserved_names=set())
    assert str(raised.value) == (f"parameter 'tasks' must be a list of strings, got {task_keys!r}")


def test_parse_task_specs_passes_entry_errors_on() -> None:
    entries = {'fib_key': entry(blocking='yes')}
    with pytest.raises(ConfigurationError, match=r"^task 'fib': fib_key\.blocking must be bool"):
        parse_task_specs(['fib_key'], entries, reserved_names=set())


# ---- unknown_keys ----------------------------------------------------------------------------


def test_unknown_keys_lists_typos_sorted() -> None:
    typos = entry(blockng=True, cancel_timout=2, Reentrant=True)
    assert unknown_keys(typos) == ['Reentrant', 'blockng', 'cancel_timout']


def test_unknown_keys_is_empty_for_every_known_key() -> None:
    full = service_entry(
        blocking=True,
        cancel_on_stop=True,
        reentrant=True,
        cancel_reported_as_success=True,
        service_success_field='success',
        cancel_timeout=1,
        resources=['base'],
        priority=1,
        on_conflict='queue',
        timeout_sec=1,
        queue_timeout_sec=1,
        feedback_timeout_sec=0,
        retry=dict.fromkeys(RETRY_KEYS, 1),
    )
    assert unknown_keys(full) == []


def test_unknown_keys_names_typos_inside_retry_nested_or_flat() -> None:
    nested = entry(retry={'max_attempts': 2, 'max_atempts': 3, 'delay': 1})
    flat = entry(**{'retry.max_attempts': 2, 'retry.max_atempts': 3, 'retry.delay': 1})
    assert unknown_keys(nested) == unknown_keys(flat) == ['retry.delay', 'retry.max_atempts']


def test_unknown_keys_names_a_misspelt_map_with_its_keys() -> None:
    assert unknown_keys(entry(**{'retyr.max_attempts': 2})) == ['retyr.max_attempts']


# ---- properties ------------------------------------------------------------------------------

identifiers = st.from_regex(r'[A-Za-z][A-Za-z0-9_]{0,15}', fullmatch=True)
cancel_timeouts = st.integers(0, 604_800) | st.floats(0, 604_800, allow_nan=False)
options = st.fixed_dictionaries(
    {},
    optional={
        'blocking': st.booleans(),
        'cancel_on_stop': st.booleans(),
        'reentrant': st.booleans(),
        'cancel_reported_as_success': st.booleans(),
        'cancel_timeout': cancel_timeouts,
    },
)


@FAST
@given(
    package=identifiers,
    kind=st.sampled_from([TaskKind.ACTION, TaskKind.SERVICE]),
    name=identifiers,
    separator=st.sampled_from(['.', '/']),
)
def test_interface_names_round_trip(
    package: str, kind: TaskKind, name: str, separator: str
) -> None:
    interface = parse_interface_name(separator.join([package, kind.value, name]))
    assert interface == InterfaceName(package, kind, name)
    assert parse_interface_name(str(interface)) == interface


@FAST
@given(
    values=options,
    is_service=st.booleans(),
    success_field=st.none() | identifiers,
    separator=st.sampled_from(['.', '/']),
)
def test_valid_options_round_trip_into_the_spec(
    values: dict[str, Any], is_service: bool, success_field: str | None, separator: str
) -> None:
    kind = 'srv' if is_service else 'action'
    raw = dict(values)
    if is_service and success_field is not None:
        raw['service_success_field'] = success_field
    spec = parse_task_spec('key', entry(msg_interface=separator.join(['pkg', kind, 'Name']), **raw))
    for option in BOOL_OPTIONS:
        assert getattr(spec, option) is values.get(option, False)
    assert spec.service_success_field == raw.get('service_success_field', '')
    assert spec.cancel_timeout_sec == float(values.get('cancel_timeout', 5.0))
    assert type(spec.cancel_timeout_sec) is float
    assert spec.kind is (TaskKind.SERVICE if is_service else TaskKind.ACTION)
    assert unknown_keys(entry(**raw)) == []
