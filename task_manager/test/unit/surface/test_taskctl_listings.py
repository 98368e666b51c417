"""taskctl's listings without a node: one vocabulary (`--limit`), every listing as JSON of the
shapes docs/taskctl.md documents (exact output), every verb in `taskctl --help`."""

import importlib
import json
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from dataclasses import replace
from datetime import UTC, datetime, timedelta
from types import SimpleNamespace
from typing import Any

import pytest
import typer
from rich.console import Console
from typer.testing import CliRunner

from task_manager.cli.common import time_text
from task_manager.client import ActiveTaskInfo, Decision, Pause, TaskResult, TaskState
from task_manager.core.status import ErrorCode, TaskStatus

T0 = datetime(2026, 11, 25, 8, 0, tzinfo=UTC)
VERBS = (
    'start', 'mission', 'cancel', 'stop', 'pause', 'resume', 'confirm', 'reprioritize', 'why',
    'active', 'results', 'history', 'stats', 'tasks', 'schedule',
)  # fmt: skip
SCHEDULE_VERBS = ('add', 'list', 'remove', 'disable', 'enable')


def _at(seconds: float) -> datetime:
    return T0 + timedelta(seconds=seconds)


# A drive paused once by the operator and resumed from the UI, then DONE: 10 s from start to
# end, 2.5 s of them paused.
DRIVE = TaskState(
    'drive',
    'navigate',
    TaskStatus.DONE,
    'CLI',
    mission_id='tour',
    received_at=_at(0),
    started_at=_at(0.5),
    ended_at=_at(10.5),
    result={'x': 1.0},
    sequence=7,
    paused=timedelta(seconds=2.5),
    pauses=[Pause(_at(2), 'operator', _at(4.5), 'UI')],
)
DRIVE_RESULT = {
    'task_id': 'drive',
    'task_name': 'navigate',
    'status': 'DONE',
    'error_code': '',
    'source': 'CLI',
    'result': {'x': 1.0},
    'received_at': '2026-11-25T08:00:00+00:00',
    'started_at': '2026-11-25T08:00:00.500000+00:00',
    'ended_at': '2026-11-25T08:00:10.500000+00:00',
    'duration_sec': 7.5,
    'paused_sec': 2.5,
}
DRIVE_PAUSES = [
    {
        'paused_at': '2026-11-25T08:00:02+00:00',
        'paused_by': 'operator',
        'resumed_at': '2026-11-25T08:00:04.500000+00:00',
        'resumed_by': 'UI',
    }
]


class FakeClient:
    """Stands for TaskManagerClient: answers with what the test gives, records the calls."""

    def __init__(self, **answers: Any) -> None:
        self.answers = answers
        self.calls: list[tuple[str, tuple[Any, ...], dict[str, Any]]] = []
        self.events_connected = False

    def __getattr__(self, method: str) -> Any:
        def record(*args: Any, **kwargs: Any) -> Any:
            self.calls.append((method, args, kwargs))
            return self.answers[method]

        return record

    def active_task_updates(self) -> Iterator[list[ActiveTaskInfo]]:
        self.calls.append(('active_task_updates', (), {}))  # the client follows from the call
        return iter(self.answers['active_task_updates'])


@pytest.fixture(scope='module')
def cli() -> SimpleNamespace:
    """taskctl's modules."""
    return SimpleNamespace(
        main=importlib.import_module('task_manager.cli.main'),
        records=importlib.import_module('task_manager.cli.records'),
        verbs=[
            importlib.import_module(f'task_manager.cli.verbs.{name}')
            for name in ('watch', 'history', 'tasks', 'decisions')
        ],
    )


@pytest.fixture
def run(cli: SimpleNamespace, monkeypatch: pytest.MonkeyPatch) -> Any:
    """`run(client, *args)`: taskctl with a fake client; the CliRunner result."""

    def invoke(client: FakeClient, *args: str) -> Any:
        @contextmanager
        def connected(
            ctx: typer.Context, events: bool = False, services: Collection[str] = ()
        ) -> Iterator[FakeClient]:
            yield client

        for module in cli.verbs:
            monkeypatch.setattr(module, 'connected', connected)
        return CliRunner().invoke(cli.main.app, list(args))

    return invoke


def _lines(output: str) -> list[Any]:
    return [json.loads(line) for line in output.splitlines()]


def test_help_lists_every_verb(cli: SimpleNamespace) -> None:
    runner = CliRunner()
    top = runner.invoke(cli.main.app, ['--help'], env={'COLUMNS': '200'})
    results = runner.invoke(cli.main.app, ['results', '--help'], env={'COLUMNS': '200'})

    listed = [line.split()[1] for line in top.stdout.splitlines() if line.startswith('│ ')]
    assert [verb for verb in listed if verb in VERBS] == list(VERBS)
    assert f'({", ".join(SCHEDULE_VERBS)})' in top.stdout
    assert '--limit' in results.stdout and '--last' not in results.stdout  # an old name


@pytest.mark.parametrize('how_many', [['--limit', '2'], ['--last', '2']])
def test_results_limit_and_its_old_name_last(run: Any, how_many: list[str]) -> None:
    client = FakeClient(recent_results=[DRIVE.to_result()])

    result = run(client, 'results', *how_many, '--json')

    assert (result.exit_code, result.stderr) == (0, '')
    assert client.calls == [('recent_results', (2,), {})]
    assert _lines(result.stdout) == [DRIVE_RESULT]


def test_results_default_to_the_latest_20(run: Any) -> None:
    client = FakeClient(recent_results=[])

    assert run(client, 'results').exit_code == 0
    assert client.calls == [('recent_results', (20,), {})]


def test_results_follow_follows_before_it_reads_the_kept_ones_and_shows_each_once(
    run: Any,
) -> None:
    """A task that ended between the kept results' answer and the start of following was
    lost; one that ends just as following starts is in both, and shown once."""
    drive = DRIVE.to_result()
    later = replace(drive, task_id='later', ended_at=_at(20))
    client = FakeClient(recent_results=[drive], results=[drive, later])

    result = run(client, 'results', '--follow', '--json')

    assert (result.exit_code, result.stderr) == (0, '')
    assert [method for method, _, _ in client.calls] == ['results', 'recent_results']
    assert [line['task_id'] for line in _lines(result.stdout)] == ['drive', 'later']


class TeardownCrashError(Exception):
    """Stands for the middleware failing as the client closes."""


@pytest.mark.parametrize(
    ('args', 'answers', 'said'),
    [
        (['confirm', 'tray'], {'confirm': SimpleNamespace(taken=True)}, 'tray  confirmed\n'),
        (
            ['reprioritize', 'drive', '7'],
            {
                'reprioritize': TaskResult(
                    'p', 'system/reprioritize', TaskStatus.DONE, ErrorCode.NONE,
                    {'successful_changes': ['drive']},
                )
            },
            'drive  priority 7\n',
        ),
    ],
)  # fmt: skip
def test_a_change_is_told_before_the_client_closes(
    cli: SimpleNamespace,
    monkeypatch: pytest.MonkeyPatch,
    args: list[str],
    answers: dict[str, Any],
    said: str,
) -> None:
    """A confirmation the Task Manager took is printed even if closing the client fails."""

    @contextmanager
    def connected(
        ctx: typer.Context, events: bool = False, services: Collection[str] = ()
    ) -> Iterator[FakeClient]:
        yield FakeClient(**answers)
        raise TeardownCrashError

    for verb in ('confirm', 'decisions'):
        monkeypatch.setattr(
            importlib.import_module(f'task_manager.cli.verbs.{verb}'), 'connected', connected
        )

    result = CliRunner().invoke(cli.main.app, args)

    assert isinstance(result.exception, TeardownCrashError)
    assert result.stdout == said


def test_history_json_has_the_mission_the_sequence_and_the_pauses(run: Any) -> None:
    client = FakeClient(history=[DRIVE])

    result = run(client, 'history', '--limit', '5', '--json')

    assert (result.exit_code, result.stderr) == (0, '')
    assert client.calls[0][2]['limit'] == 5
    assert _lines(result.stdout) == [
        {**DRIVE_RESULT, 'mission_id': 'tour', 'sequence': 7, 'pauses': DRIVE_PAUSES}
    ]


def test_active_json_a_line_per_task_and_a_list_per_change_with_watch(run: Any) -> None:
    queued = TaskState('queued', 'navigate', TaskStatus.RECEIVED, 'CLOUD', received_at=_at(1))
    client = FakeClient(
        task_states=[queued],
        active_task_updates=[[ActiveTaskInfo('queued', 'navigate', TaskStatus.RECEIVED, 'CLOUD')]],
    )
    queued_data: dict[str, Any] = {
        'task_id': 'queued',
        'task_name': 'navigate',
        'status': 'RECEIVED',
        'source': 'CLOUD',
        'mission_id': '',
        'received_at': '2026-11-25T08:00:01+00:00',
        'started_at': None,
        'duration_sec': None,
        'paused_sec': 0.0,
        'pauses': [],
        'priority': 0,
        'queue_position': 0,
        'attempt': 1,
        'prompt': '',
    }

    once = run(client, 'active', '--json')
    watched = run(client, 'active', '--watch', '--json')

    assert (once.exit_code, watched.exit_code) == (0, 0)
    assert _lines(once.stdout) == [queued_data]
    assert _lines(watched.stdout) == [[queued_data], [queued_data]]


@pytest.mark.parametrize('as_json', [[], ['--json']])
def test_active_watch_follows_the_lists_before_it_reads_the_states(
    run: Any, as_json: list[str]
) -> None:
    """A list published between the states' answer and the start of following was lost: a
    task started then never showed until the next change (the suite saw it once)."""
    client = FakeClient(task_states=[], active_task_updates=[])

    run(client, 'active', '--watch', *as_json)

    assert [method for method, _, _ in client.calls] == ['active_task_updates', 'task_states']


def test_active_shows_the_prompt_of_a_waiting_confirmation(run: Any) -> None:
    waiting = TaskState(
        'tray',
        'system/confirm',
        TaskStatus.IN_PROGRESS,
        'CLI',
        started_at=_at(1),
        feedback={'prompt': 'Load the tray', 'remaining_sec': 599.0},
    )
    other = TaskState('drive', 'navigate', TaskStatus.IN_PROGRESS, 'CLI', feedback={'prompt': 1})
    client = FakeClient(task_states=[waiting, other], active_task_updates=[])

    table = run(client, 'active')
    as_json = run(client, 'active', '--json')
    alone = run(FakeClient(task_states=[other], active_task_updates=[]), 'active')

    assert 'waiting for an answer' in table.stdout and 'Load the tray' in table.stdout
    assert [row['prompt'] for row in _lines(as_json.stdout)] == ['Load the tray', '']
    assert 'waiting for an answer' not in alone.stdout  # the column only while one waits


def test_an_active_paused_task_as_json_stops_its_clock(cli: SimpleNamespace) -> None:
    open_pause = Pause(_at(3), 'operator')
    paused = TaskState(
        'drive', 'navigate', TaskStatus.PAUSED, 'CLI', started_at=_at(1), pauses=[open_pause]
    )
    without_stamps = ActiveTaskInfo('other', 'spin', TaskStatus.IN_PROGRESS, 'UI')

    data = cli.records.active_data(paused, now=_at(10))
    bare = cli.records.active_data(without_stamps, now=_at(10))

    assert (data['duration_sec'], data['paused_sec']) == (2.0, 7.0)
    assert data['pauses'] == [
        {
            'paused_at': '2026-11-25T08:00:03+00:00',
            'paused_by': 'operator',
            'resumed_at': None,
            'resumed_by': '',
        }
    ]
    assert (bare['status'], bare['started_at'], bare['duration_sec']) == ('IN_PROGRESS', None, None)


def test_tasks_json_a_line_per_declared_task(run: Any) -> None:
    declared = [
        {
            'key': 'nav',
            'task_name': 'navigate',
            'msg_interface': 'nav2_msgs/action/NavigateToPose',
            'topic': '/navigate_to_pose',
            'blocking': True,
            'cancel_timeout': 2,
            'pause': 'restart',
        },
        {'key': '', 'task_name': 'system/stop', 'msg_interface': 'std_srvs/srv/Trigger'},
    ]

    result = run(FakeClient(declared_tasks=declared), 'tasks', '--json')

    assert (result.exit_code, result.stderr) == (0, '')
    flags = {'cancel_on_stop': False, 'reentrant': False, 'cancel_reported_as_success': False}
    assert _lines(result.stdout) == [
        {
            'task_name': 'navigate',
            'msg_interface': 'nav2_msgs/action/NavigateToPose',
            'topic': '/navigate_to_pose',
            'blocking': True,
            **flags,
            'cancel_timeout_sec': 2.0,
        },
        {
            'task_name': 'system/stop',
            'msg_interface': 'std_srvs/srv/Trigger',
            'topic': '',
            'blocking': False,
            **flags,
            'cancel_timeout_sec': 5.0,
        },
    ]


def test_a_result_without_stamps_has_null_times(cli: SimpleNamespace) -> None:
    plain = TaskResult('t', 'spin', TaskStatus.ERROR, ErrorCode.UNKNOWN_TASK, {'error': 'no'})

    data = cli.records.result_data(plain)

    assert [data[k] for k in ('received_at', 'started_at', 'ended_at', 'duration_sec')] == [
        None,
        None,
        None,
        None,
    ]
    assert (data['error_code'], data['paused_sec']) == ('unknown_task', 0.0)


def test_an_active_queued_task_has_its_place_and_priority(cli: SimpleNamespace) -> None:
    queued = TaskState(
        'dock-1', 'dock', TaskStatus.QUEUED, 'CLI', received_at=_at(1), queue_position=2, priority=3
    )
    bare = ActiveTaskInfo('dock-1', 'dock', TaskStatus.QUEUED, 'CLI')
    console = Console(width=120, record=True, file=open('/dev/null', 'w'))  # noqa: SIM115

    console.print(cli.verbs[0].active_table([queued, bare]))

    data = cli.records.active_data(queued, now=_at(10))
    assert (data['status'], data['queue_position'], data['priority'], data['attempt']) == (
        'QUEUED',
        2,
        3,
        1,
    )
    assert [cli.records.active_data(bare, now=_at(10))[k] for k in ('priority', 'attempt')] == [
        None,
        None,
    ]
    rows = [line.split('│')[3:7] for line in console.export_text().splitlines() if 'dock-1' in line]
    assert [[cell.strip() for cell in row] for row in rows] == [
        ['QUEUED #2', 'CLI', '', '3'],
        ['QUEUED', 'CLI', '', ''],
    ]


def test_why_prints_a_line_per_decision_or_json(run: Any) -> None:
    at = datetime.now(UTC).replace(microsecond=0)
    decisions = [
        Decision(at, 'queued', 'queued behind drive-1 (priority 5), which holds base'),
        Decision(at + timedelta(seconds=4), 'started', 'its turn came after drive-1 ended'),
    ]
    client = FakeClient(why=decisions)

    lines = run(client, 'why', 'dock-1')
    as_json = run(client, 'why', 'dock-1', '--json')
    nothing = run(FakeClient(why=[]), 'why', 'quick')

    assert (lines.exit_code, lines.stderr) == (0, '')
    local = time_text(at)
    assert lines.stdout.splitlines()[0] == (
        f'{local}  queued         queued behind drive-1 (priority 5), which holds base'
    )
    later = time_text(at + timedelta(seconds=4))
    assert (
        lines.stdout.splitlines()[1] == f'{later}  started        its turn came after drive-1 ended'
    )
    assert client.calls[0] == ('why', ('dock-1',), {})
    assert _lines(as_json.stdout)[0] == {
        'at': at.isoformat(),
        'decision': 'queued',
        'reason': 'queued behind drive-1 (priority 5), which holds base',
    }
    assert (nothing.exit_code, nothing.stdout) == (0, '')
    assert 'quick: no decision taken' in nothing.stderr
