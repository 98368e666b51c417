"""Schedules in the Python client: the system/schedule requests it builds, and ScheduleInfo
from real messages."""

from datetime import UTC, datetime, timedelta, timezone
from typing import Any
from zoneinfo import ZoneInfo

import pytest
from builtin_interfaces.msg import Time
from task_manager_msgs.msg import Schedule
from task_manager_msgs.srv import GetSchedules

from task_manager.client import Subtask, TaskResult
from task_manager.client.schedules import (
    ScheduleInfo,
    When,
    WhenKeywords,
    iso_8601,
    schedule_request,
    scheduled_next_run,
    when_of,
)
from task_manager.client.scheduling import Scheduling
from task_manager.core.names import GET_SCHEDULES_SERVICE
from task_manager.core.schedules.schedule import OverlapPolicy
from task_manager.core.status import ErrorCode, TaskStatus

PARIS = ZoneInfo('Europe/Paris')
NIGHT = datetime(2026, 11, 25, 2, 0, tzinfo=PARIS)
EPOCH = 1_800_000_000  # 2027-01-15T08:00:00Z


def test_a_cron_schedule_request_has_every_field_of_the_service() -> None:
    request = schedule_request(
        'dock', {'bay': 2}, cron=' 0 2 * * * ', time_zone='Europe/Paris', overlap='buffer_one'
    )

    assert request == {
        'schedule_id': '', 'task_name': 'dock', 'task_data': '{"bay": 2}', 'at': '',
        'delay_sec': 0.0, 'period_sec': 0.0, 'cron': '0 2 * * *', 'time_zone': 'Europe/Paris',
        'window_start': '', 'window_end': '', 'max_runs': 0, 'overlap': 'BUFFER_ONE',
        'misfire_grace_sec': -1.0,
    }  # fmt: skip


def test_times_are_iso_8601_with_their_zone_and_spans_seconds() -> None:
    request = schedule_request(
        'dock',
        '{}',
        period=timedelta(hours=2),
        window_start=NIGHT,
        window_end='2026-12-01T00:00:00Z',
        misfire_grace=0,
        max_runs=3,
        schedule_id='nightly',
    )

    assert request['period_sec'] == 7200.0
    assert request['window_start'] == '2026-11-25T02:00:00+01:00'
    assert request['window_end'] == '2026-12-01T00:00:00Z'
    assert (request['misfire_grace_sec'], request['max_runs']) == (0.0, 3)
    assert (request['schedule_id'], request['task_data']) == ('nightly', '{}')


def test_once_at_a_time_or_after_a_delay() -> None:
    utc = datetime(2026, 11, 25, 1, tzinfo=UTC)
    new_york = NIGHT.astimezone(timezone(timedelta(hours=-5)))

    assert schedule_request('x', None, at=utc)['at'] == '2026-11-25T01:00:00+00:00'
    assert schedule_request('x', None, at=new_york)['at'] == '2026-11-24T20:00:00-05:00'
    assert schedule_request('x', None, delay=90)['delay_sec'] == 90.0
    assert schedule_request('x', None, delay=timedelta(minutes=10))['delay_sec'] == 600.0


def test_a_naive_datetime_is_refused() -> None:
    with pytest.raises(ValueError, match=r'at 2026-11-25T02:00:00 has no time zone; give an aware'):
        schedule_request('x', None, at=datetime(2026, 11, 25, 2))
    with pytest.raises(ValueError, match='window_end'):
        schedule_request('x', None, delay=5, window_end=datetime(2026, 11, 25, 2))
    with pytest.raises(ValueError, match='has no time zone'):
        iso_8601(datetime(2026, 1, 1), 'at')


@pytest.mark.parametrize(
    ('when', 'got'),
    [
        ({}, 'none'),
        ({'at': NIGHT, 'cron': '0 2 * * *'}, 'at and cron'),
        ({'delay': 5, 'period': 10}, 'delay and period'),
    ],
)
def test_exactly_one_when_is_required(when: dict[str, Any], got: str) -> None:
    with pytest.raises(ValueError, match=f'give exactly one of at, delay, period, cron; got {got}'):
        schedule_request('x', None, **when)


@pytest.mark.parametrize(
    ('options', 'message'),
    [
        ({'period': 0}, 'period must be more than 0 s, got 0 s'),
        ({'delay': -1.0}, 'delay must be more than 0 s, got -1 s'),
        ({'period': float('nan')}, 'period must be more than 0 s'),
        ({'delay': 1, 'misfire_grace': -5}, 'misfire_grace must be 0 s or more, got -5 s'),
        ({'delay': 1, 'max_runs': -1}, r'max_runs must be 0 \(no limit\) or more, got -1'),
        ({'delay': 1, 'overlap': 'sometimes'}, "overlap 'sometimes' is not an overlap policy; "
         'use one of SKIP, BUFFER_ONE, CANCEL_OTHER, ALLOW_ALL'),
    ],
)  # fmt: skip
def test_bad_values_say_what_is_allowed(options: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        schedule_request('x', None, **options)


def test_when_is_one_value_or_its_fields_as_keywords() -> None:
    nightly = When(cron='0 2 * * *', time_zone='Europe/Paris', max_runs=3)

    assert schedule_request('x', None, nightly) == schedule_request(
        'x', None, cron='0 2 * * *', time_zone='Europe/Paris', max_runs=3
    )
    assert when_of(None, {'period': 60}) == When(period=60)
    assert when_of(nightly, {}) is nightly
    assert set(WhenKeywords.__annotations__) == set(When.__dataclass_fields__)
    with pytest.raises(ValueError, match=r'a When or its fields as keywords, not both \(got when'):
        schedule_request('x', None, nightly, period=60)


def test_a_when_is_checked_when_made() -> None:
    with pytest.raises(ValueError, match='give exactly one of at, delay, period, cron; got none'):
        When()
    with pytest.raises(ValueError, match='period must be more than 0 s'):
        When(period=0)
    assert When(delay=5).runs_once and When(period=5, max_runs=1).runs_once
    assert not When(cron='0 2 * * *').runs_once


def test_the_next_run_of_a_schedule_result() -> None:
    made = TaskResult(
        'id', 'system/schedule', TaskStatus.DONE, ErrorCode.NONE,
        {'success': True, 'schedule_id': 's', 'next_run': {'sec': EPOCH, 'nanosec': 5_000_000}},
    )  # fmt: skip
    none = TaskResult('id', 'system/schedule', TaskStatus.DONE, ErrorCode.NONE, {})
    zero = TaskResult(
        'id', 'system/schedule', TaskStatus.DONE, ErrorCode.NONE,
        {'next_run': {'sec': 0, 'nanosec': 0}},
    )  # fmt: skip

    assert scheduled_next_run(made) == datetime.fromtimestamp(EPOCH + 0.005, UTC)
    assert scheduled_next_run(none) is None and scheduled_next_run(zero) is None


def _schedule_message(**fields: Any) -> Any:
    values: dict[str, Any] = {
        'schedule_id': 'nightly',
        'task_name': 'system/mission',
        'task_data': '{"subtasks": []}',
        'created_by': 'CLI',
        'description': "cron '0 2 * * *' (Europe/Paris)",
        'cron': '0 2 * * *',
        'time_zone': 'Europe/Paris',
        'overlap': 'SKIP',
        'misfire_grace_sec': 900.0,
        'enabled': True,
        'created': Time(sec=EPOCH - 3600),
        'next_run': Time(sec=EPOCH, nanosec=500_000_000),
        'last_run': Time(sec=EPOCH - 60),
        'last_task_id': 'nightly-run-3',
        'last_status': 'DONE',
        'run_count': 3,
        'missed_count': 1,
        'skipped_count': 2,
        **fields,
    }
    return Schedule(**values)


def test_schedule_info_from_a_message() -> None:
    info = ScheduleInfo.from_message(_schedule_message())

    assert (info.schedule_id, info.task_name, info.created_by) == (
        'nightly',
        'system/mission',
        'CLI',
    )
    assert info.task_data == {'subtasks': []}
    assert (info.cron, info.time_zone, info.overlap) == (
        '0 2 * * *',
        'Europe/Paris',
        OverlapPolicy.SKIP,
    )
    assert info.next_run == datetime.fromtimestamp(EPOCH + 0.5, UTC)
    assert info.next_run is not None and info.next_run.tzinfo is UTC
    assert info.created == datetime.fromtimestamp(EPOCH - 3600, UTC)
    assert (info.last_run, info.last_task_id, info.last_status) == (
        datetime.fromtimestamp(EPOCH - 60, UTC),
        'nightly-run-3',
        TaskStatus.DONE,
    )
    assert (info.run_count, info.missed_count, info.skipped_count) == (3, 1, 2)
    assert info.misfire_grace == timedelta(minutes=15) and info.enabled
    assert info.run_source == 'schedule:nightly'


def test_zero_stamps_and_empty_fields_are_none() -> None:
    info = ScheduleInfo.from_message(
        _schedule_message(
            cron='',
            period_sec=7200.0,
            next_run=Time(),
            last_run=Time(),
            last_status='',
            overlap='',
            enabled=False,
        )
    )

    assert (info.at, info.window_start, info.window_end) == (None, None, None)
    assert (info.next_run, info.last_run, info.last_status) == (None, None, None)
    assert (info.period, info.overlap, info.enabled) == (
        timedelta(hours=2),
        OverlapPolicy.SKIP,
        False,
    )
    assert ScheduleInfo.from_message(_schedule_message()).period is None


def test_the_window_and_the_time_of_a_one_shot() -> None:
    info = ScheduleInfo.from_message(
        _schedule_message(
            at=Time(sec=EPOCH), window_start=Time(sec=EPOCH - 10), window_end=Time(sec=EPOCH + 10)
        )
    )

    assert info.at == datetime.fromtimestamp(EPOCH, UTC)
    assert info.window_start == info.at - timedelta(seconds=10)
    assert info.window_end == info.at + timedelta(seconds=10)


class RecordingClient(Scheduling):
    """The client's schedules, recording the system tasks they would run and the services
    they would call instead."""

    def __init__(self, response: Any = None) -> None:
        self.started: list[tuple[str, Any, dict[str, Any]]] = []
        self.calls: list[tuple[Any, str, Any, float | None]] = []
        self._response = response

    def _system_task(
        self, task_name: str, data: dict[str, Any], *, source: str, timeout_sec: float | None
    ) -> TaskResult:
        self.started.append((task_name, data, {'timeout_sec': timeout_sec, 'source': source}))
        return TaskResult('id', task_name, TaskStatus.DONE, ErrorCode.NONE, {})

    def _call(
        self, service_type: Any, name: str, request: Any, timeout_sec: float | None = None
    ) -> Any:
        self.calls.append((service_type, name, request, timeout_sec))
        return self._response


def _schedules(client: RecordingClient) -> Scheduling:
    return client


def test_schedule_task_runs_system_schedule() -> None:
    client = RecordingClient()

    _schedules(client).schedule_task(
        'dock', {'bay': 1}, When(delay=60), schedule_id='soon', source='UI'
    )

    ((task_name, data, options),) = client.started
    assert (task_name, options) == ('system/schedule', {'timeout_sec': None, 'source': 'UI'})
    assert data == schedule_request('dock', {'bay': 1}, delay=60, schedule_id='soon')


def test_schedule_mission_sends_the_mission_of_start_mission() -> None:
    client = RecordingClient()
    subtasks = [Subtask('nav', {'x': 1.0}), Subtask('dock', '{"bay": 2}', allow_skipping=True)]

    _schedules(client).schedule_mission(subtasks, When(cron='0 2 * * *', time_zone='Europe/Paris'))

    ((task_name, data, _),) = client.started
    assert (task_name, data['task_name'], data['cron']) == (
        'system/schedule',
        'system/mission',
        '0 2 * * *',
    )
    assert data['task_data'] == (
        '{"subtasks": [{"task_id": "", "task_name": "nav", "task_data": "{\\"x\\": 1.0}", '
        '"allow_skipping": false}, {"task_id": "", "task_name": "dock", "task_data": '
        '"{\\"bay\\": 2}", "allow_skipping": true}]}'
    )


def test_fixed_subtask_ids_are_refused_in_a_repeating_schedule_only() -> None:
    client = RecordingClient()
    subtasks = [Subtask('nav', task_id='leg-1')]

    schedules = _schedules(client)

    with pytest.raises(ValueError, match='subtask ids leg-1 would repeat in every run'):
        schedules.schedule_mission(subtasks, When(period=3600))
    schedules.schedule_mission(subtasks, When(delay=10))
    schedules.schedule_mission(subtasks, When(period=3600, max_runs=1))

    assert len(client.started) == 2


def test_unschedule_and_enable_run_their_system_tasks() -> None:
    client = RecordingClient()

    _schedules(client).unschedule(['a', 'b'])
    _schedules(client).enable_schedules(['a'], False, source='UI')

    assert [(name, data) for name, data, _ in client.started] == [
        ('system/unschedule', {'schedule_ids': ['a', 'b']}),
        ('system/enable_schedule', {'schedule_ids': ['a'], 'enabled': False}),
    ]


def test_schedules_asks_get_schedules() -> None:
    response = GetSchedules.Response(schedules=[_schedule_message()])
    client = RecordingClient(response)
    schedules = _schedules(client)

    every = schedules.schedules()
    some = schedules.schedules(['nightly', 'other'], timeout_sec=2.0)

    assert [s.schedule_id for s in every] == [s.schedule_id for s in some] == ['nightly']
    (_, name, request, timeout_sec), second = client.calls
    assert (name, list(request.schedule_ids), timeout_sec) == (GET_SCHEDULES_SERVICE, [], None)
    assert (list(second[2].schedule_ids), second[3]) == (['nightly', 'other'], 2.0)


def test_a_keyword_that_is_neither_a_when_field_nor_a_run_option_is_refused() -> None:
    client = RecordingClient()

    with pytest.raises(TypeError, match=r'unexpected keyword argument\(s\): priorty'):
        client.schedule_task('dock', period=60, priorty=3)  # type: ignore[call-arg]
    with pytest.raises(TypeError, match=r'unexpected keyword argument\(s\): bay'):
        client.schedule_mission([Subtask('dock')], delay=10, bay=2)  # type: ignore[call-arg]

    assert client.started == []
