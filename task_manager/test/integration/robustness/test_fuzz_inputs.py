"""Hypothesis against a running Task Manager: task_data, names and ids, parameters files.

Each test function starts one node and runs its examples against it; the node must answer
every request exactly once, as BEHAVIOUR.md says, and keep serving. NUL characters are not
generated in names and ids: ROS strings end at the first NUL on the wire, whoever sends them.
"""

import json
import uuid
from collections import Counter
from pathlib import Path
from typing import Any, Literal

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from test_msgs.action import Fibonacci, NestedMessage
from test_msgs.srv import BasicTypes

from task_manager.core.text.request_text import request_problem
from task_manager.testing.harness import RosHarness
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import (
    LaunchTaskManager,
    NodeProcess,
    action_task,
    service_task,
    write_params_file,
)
from task_manager.testing.servers import ScriptedActionServer, ScriptedService

TIMEOUT_SEC = 15.0
EXIT_TIMEOUT_SEC = 20.0
EXIT_CONFIGURATION_ERROR = 2
PARSING_FAILED = ('ERROR', 'task_data_parsing_failed')
DONE = ('DONE', '')
INT32 = range(-(2**31), 2**31)
SYSTEM_NAMES = {
    'system/mission',
    'system/cancel_task',
    'system/cancel_tasks',
    'system/stop',
    'system/wait',
}


def _settings(max_examples: int) -> settings:
    # Derandomized: the same examples on every run, so that CI is deterministic. New
    # inputs are explored by running with more examples and random seeds by hand.
    return settings(
        max_examples=max_examples,
        derandomize=True,
        deadline=None,
        suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    )


class Requests:
    """Requests sent to one node, with their ExecuteTask results, for the final accounting."""

    def __init__(self, tm: TaskManagerProbe) -> None:
        self.tm = tm
        self.outcomes: list[tuple[str, str, str]] = []  # (task_id, status, error_code)

    def run(self, task_name: str, task_data: str, task_id: str = '', source: str = 'fuzz') -> Any:
        result = self.tm.run(task_name, task_data, task_id=task_id, source=source)
        self.outcomes.append((result.task_id, result.task_status, result.error_code))
        return result

    def check_results_topic(self) -> None:
        """After a final valid request, /task_manager/results holds one message per request.

        Results are published in order, so once the final one is in, every earlier one is.
        """
        final = self.run('fib', json.dumps({'order': 1}), task_id='fuzz-final')
        assert (final.task_status, final.error_code) == DONE  # the node keeps serving
        self.tm.wait_result_message('fuzz-final')
        published = [(m.task_id, m.task_status, m.error_code) for m in self.tm.results.snapshot()]
        assert Counter(published) == Counter(self.outcomes)
        print(
            f'\n{len(self.outcomes)} requests: '
            f'{dict(Counter((status, error) for _, status, error in self.outcomes))}'
        )


def _instant_servers(ros: RosHarness, prefix: str) -> list[Any]:
    return [
        ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/fib', on_goal=lambda g: g.succeed()),
        ScriptedActionServer(
            ros.node, NestedMessage, f'{prefix}/nested', on_goal=lambda g: g.succeed()
        ),
        ScriptedService(ros.node, BasicTypes, f'{prefix}/basic', on_call=lambda c: c.respond()),
    ]


def _launch(launch: LaunchTaskManager, prefix: str) -> TaskManagerProbe:
    probe: TaskManagerProbe = launch(
        {
            'fib': action_task('fib', f'{prefix}/fib', reentrant=True),
            'nested': action_task(
                'nested', f'{prefix}/nested', 'test_msgs/action/NestedMessage', reentrant=True
            ),
            'basic': service_task(
                'basic', f'{prefix}/basic', 'test_msgs/srv/BasicTypes', reentrant=True
            ),
        }
    )
    return probe


# ---- (a) task_data ---------------------------------------------------------------------------

TASK_NAMES = ('fib', 'nested', 'basic')
FIELD_NAMES = sorted(
    {
        *Fibonacci.Goal.get_fields_and_field_types(),
        *NestedMessage.Goal.get_fields_and_field_types(),
        *BasicTypes.Request.get_fields_and_field_types(),
        'sec',
        'nanosec',
    }
)
keys = st.one_of(st.sampled_from(FIELD_NAMES), st.text(max_size=12))
scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(),
    st.integers(min_value=-(2**80), max_value=2**80),
    st.floats(allow_nan=False, allow_infinity=False),
    st.text(max_size=40),
)
json_values = st.recursive(
    scalars,
    lambda children: st.one_of(
        st.lists(children, max_size=5), st.dictionaries(keys, children, max_size=5)
    ),
    max_leaves=25,
)
huge_strings = st.builds(
    lambda piece, size: (piece * size)[:size],
    st.text(min_size=1, max_size=8),
    st.integers(min_value=1, max_value=100_000),
)
NON_FINITE = (
    '{"order": NaN}',
    '{"order": Infinity}',
    '{"float64_value": -Infinity}',
    '{"float64_value": 1e400}',
    '{"float32_value": NaN, "int8_value": 1}',
    '{"nested_field": {"float64_value": Infinity}}',
    'NaN',
    '-Infinity',
)


def _nested(depth: int, opener: str, closer: str, core: str) -> str:
    return opener * depth + core + closer * depth


@st.composite
def task_data_cases(draw: st.DrawFn) -> tuple[str, str, set[tuple[str, str]]]:
    """(task name, task_data text, the outcomes allowed for it)."""
    either = {PARSING_FAILED, DONE}
    name = draw(st.sampled_from(TASK_NAMES))
    case = draw(
        st.sampled_from(
            ('json', 'object', 'order', 'huge', 'deep', 'deep_inside', 'non_finite', 'text')
        )
    )
    if case == 'json':  # any JSON value, non-ASCII characters escaped or not
        value = draw(json_values)
        text = json.dumps(value, ensure_ascii=draw(st.booleans()))
        return name, text, either if isinstance(value, dict) else {PARSING_FAILED}
    if case == 'object':
        return name, json.dumps(draw(st.dictionaries(keys, json_values, max_size=6))), either
    if case == 'order':  # integers of any size for an int32 field
        order = draw(st.one_of(st.integers(), st.integers(-(2**40), 2**40)))
        if draw(st.booleans()):  # more digits than Python parses by default
            text = '{"order": ' + '9' * draw(st.integers(4000, 6000)) + '}'
            return 'fib', text, {PARSING_FAILED}
        return 'fib', json.dumps({'order': order}), {DONE if order in INT32 else PARSING_FAILED}
    if case == 'huge':
        value = draw(huge_strings)
        if name == 'basic':
            return name, json.dumps({'string_value': value}), {DONE}
        if draw(st.booleans()):
            return name, value, either  # raw text: invalid unless it happens to be an object
        return name, json.dumps({'order': value}), {PARSING_FAILED}
    if case == 'deep':  # nesting deeper than any parser's recursion, or not
        depth = draw(st.integers(min_value=1, max_value=100_000))
        opener, closer = draw(st.sampled_from((('[', ']'), ('{"a":', '}'))))
        return name, _nested(depth, opener, closer, '1'), {PARSING_FAILED}
    if case == 'deep_inside':  # an ignored key holding deep nesting next to a valid field
        depth = draw(st.integers(min_value=1, max_value=100_000))
        text = '{"order": 1, "extra": ' + _nested(depth, '[', ']', '') + '}'
        return 'fib', text, either
    if case == 'non_finite':
        return name, draw(st.sampled_from(NON_FINITE)), {PARSING_FAILED}
    return name, draw(st.text(max_size=200)), either


def test_any_task_data_gets_one_answer_and_the_node_keeps_serving(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    servers = _instant_servers(ros, topic_prefix)
    requests = Requests(_launch(launch_task_manager, topic_prefix))

    @_settings(max_examples=60)
    @given(case=task_data_cases())
    def answer_once(case: tuple[str, str, set[tuple[str, str]]]) -> None:
        name, text, allowed = case
        task_id = f'fuzz-{len(requests.outcomes)}'
        result = requests.run(name, text, task_id=task_id)
        assert result.task_id == task_id
        assert (result.task_status, result.error_code) in allowed, text[:200]
        if result.error_code:
            reason = json.loads(result.task_result)
            assert list(reason) == ['error'] and reason['error'], result.task_result

    answer_once()

    requests.check_results_topic()
    # nothing is sent to a server for data that failed to parse
    arrivals = sum(len(s.goals.items) for s in servers[:2]) + len(servers[2].calls.items)
    assert arrivals == sum(1 for _, status, _ in requests.outcomes if status == 'DONE')


# ---- (b) task names, ids and sources ---------------------------------------------------------

# typed here: mypy loses the Literal context through hypothesis' strategy decorators
SURROGATES: tuple[Literal['Cs']] = ('Cs',)
characters = st.characters(exclude_categories=SURROGATES, exclude_characters='\x00')
control_characters = st.characters(min_codepoint=1, max_codepoint=0x1F) | st.just('\x7f')
texts = st.one_of(
    st.just(''),
    st.text(characters, max_size=30),
    st.text(control_characters, min_size=1, max_size=10),
    st.builds(lambda piece: (piece * 10_000)[:10_000], st.text(characters, min_size=1, max_size=5)),
)


def test_any_name_id_and_source_are_answered_and_echoed(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    _instant_servers(ros, topic_prefix)
    tm = _launch(launch_task_manager, topic_prefix)
    requests = Requests(tm)
    sent_ids: Counter[str] = Counter()

    @_settings(max_examples=60)
    @given(name=st.one_of(st.just('fib'), texts), task_id=texts, source=texts)
    def echo(name: str, task_id: str, source: str) -> None:
        assume(name == 'fib' or name not in {*TASK_NAMES, *SYSTEM_NAMES})
        result = requests.run(name, json.dumps({'order': 1}), task_id=task_id, source=source)

        if task_id:
            assert result.task_id == task_id
        else:
            assert uuid.UUID(result.task_id).version == 4
        if request_problem(task_id, name, source):  # a control character, or too long
            expected = ('ERROR', 'invalid_request')
        else:
            expected = DONE if name == 'fib' else ('ERROR', 'unknown_task')
        assert (result.task_status, result.error_code) == expected
        sent_ids[result.task_id] += 1
        published = tm.results.wait_until(
            lambda msgs: (
                [m for m in msgs if m.task_id == result.task_id]
                if sum(m.task_id == result.task_id for m in msgs) >= sent_ids[result.task_id]
                else None
            ),
            TIMEOUT_SEC,
            'the result message',
        )[-1]
        assert (published.task_name, published.source) == (name, source)
        assert (published.task_status, published.error_code) == expected

    echo()

    requests.check_results_topic()


# ---- (c) parameters files --------------------------------------------------------------------

BASE_ENTRIES: dict[str, dict[str, Any]] = {
    'a': action_task('nav', '/fuzz/nav'),
    'b': service_task('set', '/fuzz/set', service_success_field='success'),
}
REQUIRED = ('task_name', 'topic', 'msg_interface')
BOOL_OPTIONS = ('blocking', 'cancel_on_stop', 'reentrant', 'cancel_reported_as_success')
KNOWN_KEYS = {*REQUIRED, *BOOL_OPTIONS, 'cancel_timeout', 'service_success_field'}
NODE_KEYS = {
    'tasks',
    'a',
    'b',
    'enable_task_servers',
    'server_wait_timeout',
    'goal_response_timeout',
    'results_history_size',
    'service_response_timeout',
    'server_check_period',
    'server_loss_timeout',
}

# Plain words: YAML would read 'yes', 'null', '1' and the like as other types.
words = st.from_regex(r'x[a-z]{0,8}', fullmatch=True)
# No subnormals: rcl reads them as strings (and a list holding one as a list of mixed types).
finite_floats = st.floats(min_value=-1e9, max_value=1e9, allow_subnormal=False)
# Lists of one element type only, never empty (see the xfail tests below for those).
homogeneous_lists = st.one_of(
    st.lists(st.integers(-1000, 1000), min_size=1, max_size=3),
    st.lists(st.booleans(), min_size=1, max_size=3),
    st.lists(words, min_size=1, max_size=3),
    st.lists(finite_floats, min_size=1, max_size=3),
)
not_strings = st.one_of(st.integers(-1000, 1000), finite_floats, st.booleans(), homogeneous_lists)
not_bools = st.one_of(st.integers(-1000, 1000), finite_floats, words, homogeneous_lists)
not_durations = st.one_of(
    st.floats(max_value=-1e-3, min_value=-1e9), st.integers(-1000, -1), words, st.booleans()
)
any_values = st.one_of(
    st.integers(-1000, 1000),
    finite_floats,
    st.booleans(),
    words,
    homogeneous_lists,
    st.dictionaries(words, st.integers(-1000, 1000), min_size=1, max_size=2),
)
extra_keys = st.from_regex(r'[a-z][a-z0-9_]{0,10}', fullmatch=True)


def _wrong_value(draw: st.DrawFn, entry: str, key: str) -> Any:
    """A value that makes `key` of `entry` invalid."""
    if key == 'task_name':
        other = 'set' if entry == 'a' else 'nav'
        blank_or_taken = st.sampled_from(('', '   ', other, *sorted(SYSTEM_NAMES)))
        return draw(st.one_of(not_strings, blank_or_taken))
    if key == 'topic':
        return draw(st.one_of(not_strings, st.sampled_from(('', '  '))))
    if key == 'msg_interface':
        malformed = st.sampled_from(
            (
                '',
                'Fibonacci',
                'test_msgs.msg.Empty',
                'test_msgs.action.Nope',
                'no_such_msgs/srv/Nope',
            )
        )
        return draw(st.one_of(not_strings, malformed))
    if key in BOOL_OPTIONS:
        return draw(not_bools)
    if key == 'cancel_timeout':
        return draw(st.one_of(not_durations, homogeneous_lists))
    # service_success_field: a string only on a service task, naming a bool field of its response
    return draw(st.one_of(not_strings, words, st.just('message')) if entry == 'b' else words)


@st.composite
def parameters_files(draw: st.DrawFn) -> tuple[dict[str, Any], bool]:
    """Parameters of a node (two task entries, then 1-3 changes), and whether they are valid."""
    entries = {key: dict(entry) for key, entry in BASE_ENTRIES.items()}
    parameters: dict[str, Any] = {'tasks': ['a', 'b'], **entries}
    valid = True
    broken: set[tuple[str, str]] = set()  # (entry, key) made invalid: no later change fixes it
    for _ in range(draw(st.integers(1, 3))):
        change = draw(st.sampled_from(('drop', 'wrong', 'extra', 'node_extra', 'option', 'tasks')))
        entry = draw(st.sampled_from(('a', 'b')))
        if change == 'drop':
            key = draw(st.sampled_from(REQUIRED))
            entries[entry].pop(key, None)
            broken.add((entry, key))
            valid = False
        elif change == 'wrong':
            key = draw(st.sampled_from(sorted(KNOWN_KEYS)))
            entries[entry][key] = _wrong_value(draw, entry, key)
            broken.add((entry, key))
            valid = False
        elif change == 'extra':
            key = draw(extra_keys.filter(lambda k: k not in KNOWN_KEYS))
            entries[entry][key] = draw(any_values)
        elif change == 'node_extra':
            parameters[draw(extra_keys.filter(lambda k: k not in NODE_KEYS))] = draw(any_values)
        elif change == 'option':
            key = draw(st.sampled_from((*BOOL_OPTIONS, 'cancel_timeout')))
            if (entry, key) not in broken:
                durations = st.floats(0, 1e6, allow_subnormal=False) | st.integers(0, 10**6)
                entries[entry][key] = draw(st.booleans() if key in BOOL_OPTIONS else durations)
        else:
            parameters['tasks'] = draw(
                st.one_of(
                    st.integers(-1000, 1000),
                    finite_floats,
                    st.booleans(),
                    st.sampled_from(('a', 'a, b')),
                    st.just(['a', 'b', 'c']),
                    st.just(['a', 'a']),
                    st.lists(st.integers(-1000, 1000), min_size=1, max_size=3),
                    st.just({'a': 1}),
                )
            )
            valid = False
    return parameters, valid


def test_broken_parameters_files_stop_the_node_with_one_line(tmp_path: Path) -> None:
    files = iter(range(10**6))
    seen: Counter[str] = Counter()

    @_settings(max_examples=25)
    @given(case=parameters_files())
    def one_line_or_running(case: tuple[dict[str, Any], bool]) -> None:
        parameters, valid = case
        process = NodeProcess(write_params_file(tmp_path / f'p{next(files)}.yaml', parameters))
        if valid:
            try:
                process.wait_for_log(r'Task Manager ready with 2 task\(s\): nav, set', TIMEOUT_SEC)
            finally:
                assert process.stop() == 0, process.log_lines
            assert not any('Traceback' in line for line in process.log_lines), process.log_lines
            seen['started'] += 1
            return
        exit_code = process.wait_exit(EXIT_TIMEOUT_SEC)
        assert exit_code == EXIT_CONFIGURATION_ERROR, process.log_lines
        assert len(process.log_lines) == 1, process.log_lines
        assert 'invalid configuration' in process.log_lines[0]
        seen['stopped with one line'] += 1

    one_line_or_running()
    print(f'\nparameters files: {dict(seen)}')


# ---- found by the fuzzing above --------------------------------------------------------------

PARAMETERS_THE_NODE_DOES_NOT_REPORT = {
    # rcl refuses the file while rclpy.init parses the arguments: RCLError, exit 1
    'list of mixed types': {**BASE_ENTRIES['a'], 'blocking': [1, 'x']},
    # the same, as rcl reads a subnormal float as a string
    'list with a subnormal float': {**BASE_ENTRIES['a'], 'xtra': [1.5, 2.2e-309]},
    # rclpy cannot declare a parameter without a type: ValueError, exit 1
    'empty list': {**BASE_ENTRIES['a'], 'cancel_on_stop': []},
    # the action client refuses the topic: ValueError from rcl, exit 1
    'invalid topic name': {**BASE_ENTRIES['a'], 'topic': '/has space'},
}


@pytest.mark.parametrize('case', list(PARAMETERS_THE_NODE_DOES_NOT_REPORT))
def test_parameters_refused_by_ros_stop_the_node_with_one_line(tmp_path: Path, case: str) -> None:
    parameters = {'tasks': ['a'], 'a': PARAMETERS_THE_NODE_DOES_NOT_REPORT[case]}
    process = NodeProcess(write_params_file(tmp_path / 'params.yaml', parameters))
    try:
        exit_code = process.wait_exit(EXIT_TIMEOUT_SEC)
    finally:
        process.stop()

    assert (exit_code, len(process.log_lines)) == (EXIT_CONFIGURATION_ERROR, 1), process.log_lines
    assert 'invalid configuration' in process.log_lines[0]
