"""A schedule's run options (priority, on_conflict, timeouts) without a node: what the client
and `taskctl schedule add` send, and how ScheduleInfo and `taskctl schedule list` show them."""

import importlib
import json
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from typing import Any

import pytest
import typer
from task_manager_msgs.msg import Schedule, TaskOptions
from typer.testing import CliRunner

from task_manager.client import ScheduleInfo, TaskResult
from task_manager.client.schedules import When, schedule_request
from task_manager.client.scheduling import ScheduleKeywords, Scheduling
from task_manager.client.tasks import request_options
from task_manager.core.admission.options import OnConflict, RequestOptions
from task_manager.core.status import ErrorCode, TaskStatus

schedule_verb = importlib.import_module('task_manager.cli.verbs.schedule')
cli_main = importlib.import_module('task_manager.cli.main')


class RecordingRunner(Scheduling):
    """The client's schedules, recording the system tasks they would run; answers DONE."""

    def __init__(self) -> None:
        self.started: list[tuple[str, Any, dict[str, Any]]] = []

    def _system_task(
        self, task_name: str, data: dict[str, Any], *, source: str, timeout_sec: float | None
    ) -> TaskResult:
        self.started.append((task_name, data, {'source': source, 'timeout_sec': timeout_sec}))
        return TaskResult('id', task_name, TaskStatus.DONE, ErrorCode.NONE, {})


def test_the_request_carries_the_options_given_only() -> None:
    options = request_options(priority=0, on_conflict='QUEUE', queue_timeout_sec=30)

    with_options = schedule_request('dock', None, period=60, options=options)
    without = schedule_request('dock', None, period=60, options=RequestOptions())

    assert with_options['options'] == {
        'priority': 0,
        'on_conflict': 'queue',
        'queue_timeout_sec': 30,
    }
    assert 'options' not in without
    assert without == schedule_request('dock', None, period=60)


def test_schedules_send_the_options_of_a_task_and_a_mission() -> None:
    runner = RecordingRunner()
    options: ScheduleKeywords = {
        'priority': 2,
        'on_conflict': OnConflict.REJECT,
        'task_timeout_sec': 5.0,
    }

    runner.schedule_task('dock', {}, When(delay=10), **options)
    runner.schedule_mission([], When(delay=10), **options)

    sent = [data['options'] for _, data, _ in runner.started]
    assert sent == [{'priority': 2, 'on_conflict': 'reject', 'timeout_sec': 5.0}] * 2


@pytest.mark.parametrize(
    ('options', 'message'),
    [
        ({'priority': 1.5}, 'priority must be an integer'),
        ({'on_conflict': 'wait'}, 'on_conflict must be one of preempt, queue, reject'),
        ({'queue_timeout_sec': 0}, 'queue_timeout_sec must be a finite number'),
    ],
)
def test_bad_options_are_refused_as_start_task_refuses_them(
    options: dict[str, Any], message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        request_options(**options)


def test_schedule_info_reads_the_options_of_the_message() -> None:
    given = ScheduleInfo.from_message(
        Schedule(
            schedule_id='s',
            task_data='{}',
            options=TaskOptions(has_priority=True, priority=0, on_conflict='queue'),
        )
    )
    none = ScheduleInfo.from_message(Schedule(schedule_id='s', task_data='{}'))

    assert given.options == {'priority': 0, 'on_conflict': 'queue'}
    assert none.options == {}


@pytest.fixture
def run(monkeypatch: pytest.MonkeyPatch) -> Any:
    """`run(answer, *args)`: taskctl with a client recording its calls; (result, calls)."""

    def invoke(answer: Any, *args: str) -> tuple[Any, list[tuple[str, Any, Any]]]:
        calls: list[tuple[str, Any, Any]] = []

        class Client:
            def __getattr__(self, method: str) -> Any:
                def record(*args: Any, **kwargs: Any) -> Any:
                    calls.append((method, args, kwargs))
                    return answer

                return record

        @contextmanager
        def connected(
            ctx: typer.Context, events: bool = False, services: Collection[str] = ()
        ) -> Iterator[Client]:
            yield Client()

        monkeypatch.setattr(schedule_verb, 'connected', connected)
        return CliRunner().invoke(cli_main.app, list(args)), calls

    return invoke


def test_schedule_add_passes_the_run_options(run: Any) -> None:
    answer = TaskResult('id', 'system/schedule', TaskStatus.DONE, ErrorCode.NONE, {})
    args = ('schedule', 'add', 'dock', '--in', '1m', '--priority', '3', '--on-conflict', 'queue')
    timeouts = ('--timeout', '60', '--queue-timeout', '30', '--feedback-timeout', '5')

    result, calls = run(answer, *args, *timeouts)
    plain, plain_calls = run(answer, 'schedule', 'add', 'dock', '--in', '1m')

    assert result.exit_code == plain.exit_code == 0, result.stderr
    ((_, _, kwargs),) = calls
    assert {name: kwargs[name] for name in ('priority', 'on_conflict')} == {
        'priority': 3,
        'on_conflict': 'queue',
    }
    assert (kwargs['task_timeout_sec'], kwargs['queue_timeout_sec']) == (60.0, 30.0)
    assert kwargs['feedback_timeout_sec'] == 5.0 and 'timeout_sec' not in kwargs
    ((_, _, plain_kwargs),) = plain_calls
    assert plain_kwargs['priority'] is plain_kwargs['task_timeout_sec'] is None


def test_schedule_add_refuses_a_bad_on_conflict(run: Any) -> None:
    result, calls = run(None, 'schedule', 'add', 'dock', '--in', '1m', '--on-conflict', 'wait')

    assert result.exit_code == 2 and calls == []
    assert "'wait' is not one of" in result.stderr


def test_schedule_list_shows_the_options_when_a_schedule_has_some(run: Any) -> None:
    def info(schedule_id: str, options: TaskOptions) -> ScheduleInfo:
        message = Schedule(schedule_id=schedule_id, task_data='{}', options=options)
        return ScheduleInfo.from_message(message)

    queued = info('q', TaskOptions(has_priority=True, priority=2, on_conflict='queue'))
    plain = info('p', TaskOptions())

    table, _ = run([queued, plain], 'schedule', 'list')
    no_options, _ = run([plain], 'schedule', 'list')
    as_json, _ = run([queued, plain], 'schedule', 'list', '--json')

    assert 'priority=2 on_conflict=queue' in table.stdout
    assert 'options' in table.stdout and 'options' not in no_options.stdout
    lines = [json.loads(line) for line in as_json.stdout.splitlines()]
    assert [line['options'] for line in lines] == [{'priority': 2, 'on_conflict': 'queue'}, {}]
