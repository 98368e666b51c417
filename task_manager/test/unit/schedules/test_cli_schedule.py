"""taskctl pause, resume and schedule without a node: option parsing, the calls made to a
recording client, exact output and exit codes; and PAUSED tasks in `taskctl active`."""

import importlib
import json
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime, timedelta
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
import typer
from rich.console import Console
from task_manager_msgs.msg import Schedule
from typer.testing import CliRunner

from task_manager.client import Pause, ScheduleInfo, Subtask, TaskResult, TaskState
from task_manager.core.status import ErrorCode, TaskStatus

NIGHT = datetime(2026, 11, 25, 1, 0, tzinfo=UTC)


def _result(status: TaskStatus, result: dict[str, Any], **fields: Any) -> TaskResult:
    return TaskResult('id', 'system/x', status, fields.pop('error_code', ErrorCode.NONE), result)


class RecordingClient:
    """Stands for TaskManagerClient: records each call, answers with `answer`."""

    def __init__(self, answer: Any) -> None:
        self.answer = answer
        self.calls: list[tuple[str, tuple[Any, ...], dict[str, Any]]] = []

    def __getattr__(self, method: str) -> Any:
        def record(*args: Any, **kwargs: Any) -> Any:
            self.calls.append((method, args, kwargs))
            return self.answer

        return record


@pytest.fixture(scope='module')
def cli() -> SimpleNamespace:
    """taskctl's modules."""
    return SimpleNamespace(
        main=importlib.import_module('task_manager.cli.main'),
        pause=importlib.import_module('task_manager.cli.verbs.pause'),
        schedule=importlib.import_module('task_manager.cli.verbs.schedule'),
        watch=importlib.import_module('task_manager.cli.verbs.watch'),
    )


@pytest.fixture
def run(cli: SimpleNamespace, monkeypatch: pytest.MonkeyPatch) -> Any:
    """`run(answer, *args)`: taskctl with a recording client; (result, client)."""

    def invoke(answer: Any, *args: str) -> tuple[Any, RecordingClient]:
        client = RecordingClient(answer)

        @contextmanager
        def connected(
            ctx: typer.Context, events: bool = False, services: Collection[str] = ()
        ) -> Iterator[RecordingClient]:
            yield client

        monkeypatch.setattr(cli.pause, 'connected', connected)
        monkeypatch.setattr(cli.schedule, 'connected', connected)
        return CliRunner().invoke(cli.main.app, list(args)), client

    return invoke


def test_pause_prints_a_line_per_id_and_exits_0(run: Any) -> None:
    answer = _result(TaskStatus.DONE, {'success': True, 'successful_pauses': ['a', 'b']})

    result, client = run(answer, 'pause', 'a', 'b', '--source', 'shell')

    assert (result.exit_code, result.stdout, result.stderr) == (0, 'a  paused\nb  paused\n', '')
    assert client.calls == [('pause', (['a', 'b'],), {'source': 'shell'})]


def test_a_failed_resume_prints_each_error_and_exits_1(run: Any) -> None:
    answer = _result(
        TaskStatus.ERROR,
        {
            'success': False,
            'successful_resumes': ['a'],
            'errors': ["no active task 'zz' to resume"],
        },
    )

    result, client = run(answer, 'resume', 'a', 'zz')

    assert (result.exit_code, result.stdout) == (1, 'a  resumed\n')
    assert result.stderr == "ERROR: no active task 'zz' to resume\n"
    assert client.calls == [('resume', (['a', 'zz'],), {'source': 'CLI'})]


def test_a_refused_pause_says_why_in_one_line(run: Any) -> None:
    answer = _result(
        TaskStatus.ERROR,
        {'error': "unknown task 'system/pause'"},
        error_code=ErrorCode.UNKNOWN_TASK,
    )

    result, _ = run(answer, 'pause', 'a')

    assert (result.exit_code, result.stdout) == (1, '')
    assert result.stderr == "unknown_task: unknown task 'system/pause'\n"


def test_when_options_become_schedule_task_arguments(cli: SimpleNamespace) -> None:
    options = cli.schedule.schedule_options(
        every='1h30m',
        start='2026-11-25T02:00:00+01:00',
        end='2026-12-01T00:00Z',
        max_runs=4,
        overlap='cancel_other',
        misfire_grace='15m',
        time_zone='Europe/Paris',
    )

    assert options == {
        'at': None,
        'delay': None,
        'period': 5400.0,
        'cron': '',
        'time_zone': 'Europe/Paris',
        'window_start': NIGHT,
        'window_end': datetime(2026, 12, 1, tzinfo=UTC),
        'max_runs': 4,
        'overlap': 'CANCEL_OTHER',
        'misfire_grace': 900.0,
    }


def test_a_time_without_a_zone_is_local_time(cli: SimpleNamespace) -> None:
    at = cli.schedule.schedule_options(at='2026-11-25T02:00')['at']

    assert at == datetime(2026, 11, 25, 2, 0).astimezone()
    assert at.tzinfo is not None


@pytest.mark.parametrize(
    ('options', 'message'),
    [
        ({}, 'give exactly one of --at, --in, --every, --cron; got none'),
        ({'at': '2026-11-25T02:00Z', 'cron': '0 2 * * *'}, 'got --at and --cron'),
        ({'at': 'tomorrow'}, "'tomorrow' is not an ISO 8601 time"),
        ({'every': '2 hours'}, "'2 hours' is not a span of time"),
        ({'delay': '0s'}, 'delay must be more than 0 s'),
        ({'cron': '* * * * *', 'overlap': 'queue'}, "'queue' is not an overlap policy; use skip"),
        ({'delay': '1m', 'start': '1 Jan'}, "'1 Jan' is not an ISO 8601 time"),
    ],
)
def test_bad_options_say_what_is_allowed(
    cli: SimpleNamespace, options: dict[str, Any], message: str
) -> None:
    with pytest.raises(typer.BadParameter, match=message):
        cli.schedule.schedule_options(**options)


def _scheduled(next_run_sec: int = 1_800_000_000) -> TaskResult:
    return _result(
        TaskStatus.DONE,
        {
            'success': True,
            'schedule_id': 'nightly',
            'next_run': {'sec': next_run_sec, 'nanosec': 0},
            'message': '',
        },
    )


def test_schedule_add_prints_the_id_and_the_next_run(run: Any) -> None:
    args = ('schedule', 'add', 'dock', '{"bay": 2}', '--cron', '0 2 * * *', '--tz', 'UTC')

    result, client = run(_scheduled(), *args, '--id', 'nightly', '--overlap', 'skip')

    assert result.exit_code == 0, result.stderr
    assert result.stdout.startswith('nightly  next run 2027-01-15 ')
    ((method, args, kwargs),) = client.calls
    assert (method, args) == ('schedule_task', ('dock', {'bay': 2}))
    assert (kwargs['cron'], kwargs['time_zone'], kwargs['overlap']) == ('0 2 * * *', 'UTC', 'SKIP')
    assert (kwargs['schedule_id'], kwargs['source']) == ('nightly', 'CLI')


def test_schedule_add_of_a_mission_file(run: Any, tmp_path: Path) -> None:
    path = tmp_path / 'tour.yaml'
    path.write_text('- task_name: nav\n  task_data: {x: 1}\n- task_name: dock\n')

    result, client = run(_scheduled(0), 'schedule', 'add', '--mission', str(path), '--in', '10m')

    assert (result.exit_code, result.stdout) == (0, 'nightly  no run to come\n')
    ((method, args, kwargs),) = client.calls
    assert method == 'schedule_mission' and kwargs['delay'] == 600.0
    assert args == ([Subtask('nav', '{"x": 1}'), Subtask('dock', '{}')],)


def test_schedule_add_needs_a_task_or_a_mission(run: Any, tmp_path: Path) -> None:
    neither, _ = run(_scheduled(), 'schedule', 'add', '--in', '1m')
    both, client = run(_scheduled(), 'schedule', 'add', 'x', '--in', '1m', '--mission', 'm.yaml')

    assert neither.exit_code == both.exit_code == 2
    assert 'give a TASK_NAME or --mission FILE' in neither.stderr
    assert client.calls == []


def test_a_refused_schedule_says_why_and_exits_1(run: Any) -> None:
    answer = _result(
        TaskStatus.ERROR,
        {'error': "cron '0 25 * * *' is not a cron expression"},
        error_code=ErrorCode.TASK_DATA_PARSING_FAILED,
    )

    result, _ = run(answer, 'schedule', 'add', 'dock', '--cron', '0 25 * * *')

    assert (result.exit_code, result.stdout) == (1, '')
    assert result.stderr == (
        "task_data_parsing_failed: cron '0 25 * * *' is not a cron expression\n"
    )


def _info(**fields: Any) -> ScheduleInfo:
    values: dict[str, Any] = {
        'schedule_id': 'nightly',
        'task_name': 'dock',
        'task_data': '{}',
        'description': 'every 7200 s',
        'period_sec': 7200.0,
        'enabled': True,
        'run_count': 3,
        'missed_count': 1,
        'skipped_count': 2,
        'last_status': 'DONE',
        **fields,
    }
    return ScheduleInfo.from_message(Schedule(**values))


def test_schedule_list_json(run: Any) -> None:
    result, client = run([_info(), _info(schedule_id='b', enabled=False)], 'schedule', 'list')
    as_json, _ = run([_info()], 'schedule', 'list', 'nightly', '--json')

    assert result.exit_code == 0
    for text in ('schedules (2)', 'nightly', 'every 7200 s', '3/1/2', 'DONE', 'no'):
        assert text in result.stdout
    assert client.calls == [('schedules', (None,), {})]
    line = json.loads(as_json.stdout)
    assert (line['schedule_id'], line['period_sec'], line['next_run']) == ('nightly', 7200.0, None)
    assert (line['last_status'], line['overlap'], line['enabled']) == ('DONE', 'SKIP', True)


@pytest.mark.parametrize(
    ('verb', 'method', 'args', 'field', 'word'),
    [
        ('remove', 'unschedule', (['a'],), 'removed', 'removed'),
        ('disable', 'enable_schedules', (['a'], False), 'changed', 'disabled'),
        ('enable', 'enable_schedules', (['a'], True), 'changed', 'enabled'),
    ],
)
def test_schedule_changes_print_a_line_per_id(
    run: Any, verb: str, method: str, args: tuple[Any, ...], field: str, word: str
) -> None:
    answer = _result(TaskStatus.ERROR, {'success': False, field: ['a'], 'errors': ["no 'b'"]})

    result, client = run(answer, 'schedule', verb, 'a')

    assert (result.exit_code, result.stdout, result.stderr) == (
        1,
        f'a  {word}\n',
        "ERROR: no 'b'\n",
    )
    assert client.calls == [(method, args, {'source': 'CLI'})]


def test_active_shows_a_paused_task_with_its_clock_stopped(cli: SimpleNamespace) -> None:
    started = datetime.now(UTC) - timedelta(minutes=10)
    paused = TaskState(
        't1',
        'nav',
        TaskStatus.PAUSED,
        'UI',
        started_at=started,
        pauses=[Pause(started + timedelta(seconds=42), 'operator')],
    )
    console = Console(width=120, record=True, file=open('/dev/null', 'w'))  # noqa: SIM115

    console.print(cli.watch.active_table([paused]))

    (row,) = [line for line in console.export_text().splitlines() if 't1' in line]
    assert row.split('│')[3:6] == [' PAUSED ', ' UI     ', ' 42.0 s      ']
