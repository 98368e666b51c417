"""Schedules without ROS: requests, fire times of each kind, windows, DST and coalescing."""

import itertools
import json
import time
from collections.abc import Callable
from datetime import UTC, datetime
from typing import Any
from zoneinfo import ZoneInfo

import pytest
from hypothesis import given
from hypothesis import strategies as st

from task_manager.core.admission.options import OnConflict, RequestOptions
from task_manager.core.schedules.request import parse_schedule_request
from task_manager.core.schedules.schedule import (
    CRON_COUNT_LIMIT,
    DEFAULT_MISFIRE_GRACE_SEC,
    OverlapPolicy,
    ScheduleError,
    ScheduleKind,
    ScheduleSpec,
    first_fire_time,
    latest_fire_at_or_before,
    next_fire_after,
)

PARIS, BERLIN = ZoneInfo('Europe/Paris'), ZoneInfo('Europe/Berlin')
T0 = datetime(2026, 1, 1, tzinfo=UTC).timestamp()  # a Thursday, 00:00 UTC


def utc(year: int, month: int, day: int, hour: int = 0, minute: int = 0) -> float:
    return datetime(year, month, day, hour, minute, tzinfo=UTC).timestamp()


def spec(**changes: Any) -> ScheduleSpec:
    fields: dict[str, Any] = {
        'schedule_id': 's', 'task_name': 'patrol', 'task_data': '{}', 'created_by': 'test',
        'created': T0,
    }  # fmt: skip
    return ScheduleSpec(**{**fields, **changes})


def request(now: float = T0, **fields: Any) -> ScheduleSpec:
    return parse_schedule_request({'task_name': 'patrol', **fields}, 'cli', now, lambda: 'new-1')


def fire_times(s: ScheduleSpec, count: int) -> list[float]:
    times = [first_fire_time(s)]
    while len(times) < count and times[-1] is not None:
        times.append(next_fire_after(s, times[-1]))
    return [t for t in times if t is not None]


def local(times: list[float], zone: ZoneInfo) -> list[str]:
    return [datetime.fromtimestamp(t, zone).isoformat() for t in times]


# ---- requests ----------------------------------------------------------------------------


def test_a_request_keeps_its_fields_and_fills_the_defaults() -> None:
    s = request(task_data='{"zone": 2}', period_sec=60)

    assert s == ScheduleSpec(
        schedule_id='new-1', task_name='patrol', task_data='{"zone": 2}', created_by='cli',
        created=T0, at=None, period_sec=60.0, cron='', time_zone='UTC', start=None, end=None,
        max_runs=0, overlap=OverlapPolicy.SKIP, misfire_grace_sec=DEFAULT_MISFIRE_GRACE_SEC,
    )  # fmt: skip
    assert s.kind is ScheduleKind.PERIOD


def test_a_request_keeps_its_admission_options_and_a_stored_spec_without_them_loads() -> None:
    options = RequestOptions(priority=5, on_conflict=OnConflict.QUEUE, timeout_sec=30.0)

    s = request(period_sec=60, options=options)

    assert s.options == {'priority': 5, 'on_conflict': 'queue', 'timeout_sec': 30.0}
    assert ScheduleSpec.from_json(s.to_json()) == s
    assert RequestOptions.from_dict(s.options) == options
    stored_before = json.loads(s.to_json())
    del stored_before['options']
    assert ScheduleSpec.from_json(json.dumps(stored_before)).options == {}


def test_a_request_with_unusable_options_is_refused_naming_them() -> None:
    with pytest.raises(
        ScheduleError, match=r'options: timeout_sec must be from 0 to 604800 s, got -1\.0'
    ):
        request(period_sec=60, options=RequestOptions(timeout_sec=-1.0))


def test_a_request_without_an_id_gets_a_new_one_and_keeps_a_given_one() -> None:
    assert request(period_sec=60).schedule_id == 'new-1'
    assert request(period_sec=60, schedule_id='night.patrol:2_a-b').schedule_id == (
        'night.patrol:2_a-b'
    )


def test_task_data_is_kept_as_given_even_when_empty() -> None:
    assert request(period_sec=60, task_data='').task_data == ''


@pytest.mark.parametrize(
    ('text', 'policy'),
    [('', OverlapPolicy.SKIP), ('buffer_one', OverlapPolicy.BUFFER_ONE),
     ('Cancel_Other', OverlapPolicy.CANCEL_OTHER), ('ALLOW_ALL', OverlapPolicy.ALLOW_ALL)],
)  # fmt: skip
def test_overlap_is_case_insensitive_and_skip_by_default(text: str, policy: OverlapPolicy) -> None:
    assert request(period_sec=60, overlap=text).overlap is policy


@pytest.mark.parametrize(
    ('given', 'kept'), [(-1.0, DEFAULT_MISFIRE_GRACE_SEC), (0, 0.0), (30, 30.0)]
)
def test_a_negative_misfire_grace_means_the_default(given: float, kept: float) -> None:
    assert request(period_sec=60, misfire_grace_sec=given).misfire_grace_sec == kept


def test_an_empty_time_zone_is_utc() -> None:
    assert request(cron='0 2 * * *', time_zone='').time_zone == 'UTC'
    assert request(cron='0 2 * * *', time_zone='Europe/Paris').time_zone == 'Europe/Paris'


def test_an_at_within_the_grace_in_the_past_is_accepted_and_fires_at_once() -> None:
    s = request(now=T0 + 60, at='2026-01-01T00:00:00Z')
    assert first_fire_time(s) == T0


BAD_REQUESTS = [
    ({}, 'at,delay_sec,period_sec,cron',
     r'give exactly one of at, delay_sec, period_sec, cron; got none'),
    ({'at': '2026-11-25T02:00:00Z', 'cron': '0 2 * * *'}, 'at,cron', r'one .* got at and cron'),
    ({'delay_sec': 5, 'period_sec': 5}, 'delay_sec,period_sec', r'got delay_sec and period_sec'),
    ({'at': '2026-11-25T02:00:00'}, 'at', r'has no zone; a zone offset is required, e.g. '),
    ({'at': 'tomorrow'}, 'at', r"'tomorrow' is not an ISO 8601 time; use e.g. '2026-11-25T02"),
    ({'at': 5}, 'at', r'at must be text, got int'),
    ({'delay_sec': -5}, 'delay_sec', r'delay_sec must be more than 0 s, got -5'),
    ({'delay_sec': 'soon'}, 'delay_sec', r'must be a finite number of seconds'),
    ({'delay_sec': float('nan')}, 'delay_sec', r'must be a finite number of seconds'),
    ({'period_sec': True}, 'period_sec', r'must be a finite number of seconds'),
    ({'period_sec': -60}, 'period_sec', r'period_sec must be at least 0.1 s, got -60'),
    ({'period_sec': 1e-6}, 'period_sec', r'period_sec must be at least 0.1 s'),
    ({'period_sec': 1e300}, 'period_sec',
     r'period_sec must be from 0.1 to 31622400 s, got 1e\+300'),
    ({'delay_sec': 1e300}, 'delay_sec', r'delay_sec must be from 0 to 31622400 s, got 1e\+300'),
    ({'period_sec': 60, 'misfire_grace_sec': 1e300}, 'misfire_grace_sec',
     r'misfire_grace_sec must be from 0 to 604800 s, got 1e\+300'),
    ({'period_sec': 60, 'max_runs': 2**40}, 'max_runs',
     r'max_runs must be from 0 to 2147483647, got 1099511627776'),
    ({'period_sec': 60, 'task_data': 'x' * 1_048_577}, 'task_data',
     r'task_data is 1048577 bytes; at most 1048576 are allowed'),
    ({'cron': '61 * * * *'}, 'cron',
     r"cron '61 \* \* \* \*' is not a cron expression \(5 fields: minute hour day-of-month month "
     r"day-of-week, e.g. '0 2 \* \* \*'\): "),
    ({'cron': '0 2 * * * *'}, 'cron', r'not a cron expression \(5 fields: .*\): it has 6 fields'),
    ({'cron': 'every night'}, 'cron', r'is not a cron expression \(5 fields'),
    ({'cron': '0 0 30 2 *'}, 'cron', r'the schedule has no fire time: it would never run'),
    ({'cron': '0 2 * * *', 'time_zone': 'Mars/Olympus'}, 'time_zone',
     r"time_zone 'Mars/Olympus' is not a known time zone; use an IANA name such as 'UTC'"),
    ({'period_sec': 60, 'time_zone': '../etc/passwd'}, 'time_zone', r'is not a known time zone'),
    ({'period_sec': 60, 'start': '2026-02-01T00:00:00Z', 'end': '2026-02-01T00:00:00Z'}, 'end',
     r'end 2026-02-01T00:00:00\+00:00 must be after start 2026-02-01T00:00:00\+00:00'),
    ({'period_sec': 60, 'end': 'soon'}, 'end', r"end 'soon' is not an ISO 8601 time"),
    ({'period_sec': 60, 'start': '2026-02-01'}, 'start', r"start '2026-02-01' has no zone"),
    ({'at': '2026-03-01T00:00:00Z', 'end': '2026-02-01T00:00:00Z'}, 'at',
     r'at 2026-03-01T00:00:00\+00:00 is outside the window from start - to end 2026-02-01T00'),
    ({'at': '2026-01-02T00:00:00Z', 'start': '2026-02-01T00:00:00Z'}, 'at',
     r'outside the window from start 2026-02-01T00:00:00\+00:00 to end -: give an at within it'),
    ({'at': '2025-12-31T23:44:59Z'}, 'at',
     r'at 2025-12-31T23:44:59\+00:00 is in the past \(more than misfire_grace_sec 900 s ago\)'),
    ({'period_sec': 7200, 'end': '2026-01-01T01:00:00Z'}, 'end',
     r'the schedule has no fire time before end 2026-01-01T01:00:00\+00:00: it would never run'),
    ({'cron': '0 2 * * *', 'end': '2025-12-01T00:00:00Z'}, 'end', r'no fire time before end'),
    ({'period_sec': 60, 'max_runs': -1}, 'max_runs', r'max_runs must be 0 \(unlimited\) or more'),
    ({'period_sec': 60, 'max_runs': 1.5}, 'max_runs', r'max_runs must be 0 \(unlimited\) or more'),
    ({'period_sec': 60, 'overlap': 'sometimes'}, 'overlap',
     r"overlap 'sometimes' is not an overlap policy; use one of SKIP, BUFFER_ONE, CANCEL_OTHER, "
     r"ALLOW_ALL \('' is SKIP\)"),
    ({'period_sec': 60, 'schedule_id': 'a b'}, 'schedule_id',
     r"schedule_id 'a b' is not allowed: use 1 to 64 characters among A-Z a-z 0-9 _ \. : -"),
    ({'period_sec': 60, 'schedule_id': 'a/b'}, 'schedule_id', r'use 1 to 64 characters'),
    ({'period_sec': 60, 'schedule_id': 'x' * 65}, 'schedule_id', r'use 1 to 64 characters'),
    ({'period_sec': 60, 'task_name': ''}, 'task_name', r'task_name is required: the task'),
    ({'period_sec': 60, 'task_name': '  '}, 'task_name', r'task_name is required'),
]  # fmt: skip


@pytest.mark.parametrize(('fields', 'field', 'message'), BAD_REQUESTS)
def test_a_bad_request_names_its_field_and_what_is_allowed(
    fields: dict[str, Any], field: str, message: str
) -> None:
    with pytest.raises(ScheduleError, match=message) as raised:
        parse_schedule_request({'task_name': 'patrol', **fields}, 'cli', T0, lambda: 'new-1')
    assert raised.value.field == field
    assert isinstance(raised.value, ValueError)


def test_a_request_without_a_task_name_is_refused() -> None:
    with pytest.raises(ScheduleError, match='task_name is required') as raised:
        parse_schedule_request({'period_sec': 60}, 'cli', T0, lambda: 'new-1')
    assert raised.value.field == 'task_name'


def test_a_spec_has_exactly_one_kind() -> None:
    with pytest.raises(ValueError, match='exactly one of at, period_sec, cron; got 2'):
        spec(at=T0, period_sec=60)
    with pytest.raises(ValueError, match='got 0'):
        spec()


# ---- one-shots ---------------------------------------------------------------------------


def test_a_one_shot_at_fires_once_at_its_time_with_its_zone() -> None:
    s = request(at='2026-11-25T02:00:00+01:00')

    assert s.kind is ScheduleKind.AT
    assert first_fire_time(s) == s.at == utc(2026, 11, 25, 1)
    assert next_fire_after(s, utc(2026, 11, 25, 0, 59)) == s.at
    assert next_fire_after(s, s.at) is None
    assert fire_times(s, 5) == [s.at]


def test_a_delay_fires_once_that_long_after_the_request() -> None:
    s = request(now=T0 + 10, delay_sec=90.5)
    assert (s.kind, s.at, fire_times(s, 3)) == (ScheduleKind.AT, T0 + 100.5, [T0 + 100.5])


# ---- periodic ----------------------------------------------------------------------------


def test_a_period_without_start_first_fires_one_period_after_creation() -> None:
    s = request(period_sec=7200)
    assert fire_times(s, 3) == [T0 + 7200, T0 + 14400, T0 + 21600]
    assert next_fire_after(s, T0 + 7200.5) == T0 + 14400
    assert next_fire_after(s, T0 - 1e6) == T0 + 7200


def test_a_period_with_start_is_anchored_at_start() -> None:
    s = request(period_sec=60, start='2026-01-01T00:00:10Z')
    assert fire_times(s, 3) == [T0 + 10, T0 + 70, T0 + 130]
    assert next_fire_after(s, T0 + 150) == T0 + 190
    assert next_fire_after(s, T0 + 190) == T0 + 250


def test_a_period_whose_start_is_before_its_creation_starts_on_the_next_period_time() -> None:
    s = request(now=T0 + 3600 + 30, period_sec=600, start='2026-01-01T00:00:00Z')
    assert fire_times(s, 2) == [T0 + 3600 + 600, T0 + 3600 + 1200]


def test_periodic_times_are_arithmetic_even_after_years() -> None:
    s = spec(period_sec=0.001)
    after = T0 + 3 * 365 * 86400 + 0.0005
    assert next_fire_after(s, after) == pytest.approx(after + 0.0005, abs=1e-6)


# ---- cron --------------------------------------------------------------------------------


def test_a_cron_every_quarter_of_an_hour() -> None:
    s = request(now=T0 + 7 * 60, cron='*/15 * * * *')
    assert fire_times(s, 4) == [T0 + 900, T0 + 1800, T0 + 2700, T0 + 3600]
    assert s.cron == '*/15 * * * *'


def test_a_cron_is_read_in_its_time_zone() -> None:
    s = request(cron='0 2 * * *', time_zone='Europe/Paris')
    assert first_fire_time(s) == utc(2026, 1, 1, 1)  # 02:00 in Paris is 01:00 UTC in winter


def test_a_nightly_cron_runs_once_at_0200_local_on_the_autumn_dst_night() -> None:
    now = datetime(2026, 10, 23, 12, tzinfo=PARIS).timestamp()
    s = request(now=now, cron='0 2 * * *', time_zone='Europe/Paris')

    times = fire_times(s, 4)

    # 02:00 happens twice on 25 October (summer, then winter time): it runs the first time only
    assert local(times, PARIS) == [
        '2026-10-24T02:00:00+02:00', '2026-10-25T02:00:00+02:00',
        '2026-10-26T02:00:00+01:00', '2026-10-27T02:00:00+01:00',
    ]  # fmt: skip
    assert [b - a for a, b in itertools.pairwise(times)] == [86400, 90000, 86400]


def test_a_nightly_cron_runs_at_the_first_local_time_after_a_skipped_0200() -> None:
    now = datetime(2026, 3, 27, 12, tzinfo=PARIS).timestamp()
    s = request(now=now, cron='0 2 * * *', time_zone='Europe/Paris')
    # 29 March has no 02:00 (clocks go from 02:00 to 03:00): that night it runs at 03:00
    assert local(fire_times(s, 3), PARIS) == [
        '2026-03-28T02:00:00+01:00', '2026-03-29T03:00:00+02:00', '2026-03-30T02:00:00+02:00',
    ]  # fmt: skip


def test_a_quarter_hour_cron_keeps_its_pace_through_the_repeated_hour_in_berlin() -> None:
    s = spec(cron='*/15 * * * *', time_zone='Europe/Berlin')
    start = datetime(2026, 10, 25, 2, 30, tzinfo=BERLIN).timestamp()  # summer time

    times = [start]
    for _ in range(6):
        t = next_fire_after(s, times[-1])
        assert t is not None
        times.append(t)

    assert [b - a for a, b in itertools.pairwise(times)] == [900.0] * 6
    assert local(times[1:], BERLIN) == [
        '2026-10-25T02:45:00+02:00', '2026-10-25T02:00:00+01:00', '2026-10-25T02:15:00+01:00',
        '2026-10-25T02:30:00+01:00', '2026-10-25T02:45:00+01:00', '2026-10-25T03:00:00+01:00',
    ]  # fmt: skip


def test_a_cron_that_never_matches_has_no_fire_time() -> None:
    assert first_fire_time(spec(cron='0 0 30 2 *')) is None


# ---- window ------------------------------------------------------------------------------


def test_no_run_before_start_nor_after_end() -> None:
    s = request(period_sec=60, start='2026-01-01T01:00:00Z', end='2026-01-01T01:02:00Z')
    assert fire_times(s, 10) == [T0 + 3600, T0 + 3660, T0 + 3720]  # end itself included
    assert next_fire_after(s, T0 + 3720) is None


def test_a_cron_start_is_itself_a_fire_time_and_nothing_runs_after_end() -> None:
    s = request(cron='0 2 * * *', start='2026-01-03T02:00:00Z', end='2026-01-05T01:00:00Z')
    assert fire_times(s, 10) == [utc(2026, 1, 3, 2), utc(2026, 1, 4, 2)]


def test_a_schedule_past_its_end_is_finished() -> None:
    s = spec(period_sec=60, created=T0 + 7200, end=T0 + 3600)
    assert first_fire_time(s) is None
    assert next_fire_after(s, T0) is None
    assert first_fire_time(spec(at=T0, end=T0 - 1)) is None


# ---- catching up -------------------------------------------------------------------------


def test_the_latest_periodic_time_and_the_count_since_a_due_time() -> None:
    s = spec(period_sec=10)  # 10, 20, 30, ... after T0
    assert latest_fire_at_or_before(s, T0 + 10, T0 + 10) == (T0 + 10, 1)
    assert latest_fire_at_or_before(s, T0 + 10, T0 + 95) == (T0 + 90, 9)
    assert latest_fire_at_or_before(s, T0 + 30, T0 + 100) == (T0 + 100, 8)
    ended = spec(period_sec=10, end=T0 + 50)
    assert latest_fire_at_or_before(ended, T0 + 10, T0 + 95) == (T0 + 50, 5)


def test_a_day_of_millisecond_periods_is_counted_without_walking_them() -> None:
    s = spec(period_sec=0.001, start=T0)
    began = time.perf_counter()
    latest, count = latest_fire_at_or_before(s, T0, T0 + 86400)
    assert time.perf_counter() - began < 0.1  # 86.4 million times would take minutes
    assert latest == pytest.approx(T0 + 86400)
    assert count == 86_400_001


def test_the_latest_cron_time_and_the_count_since_a_due_time() -> None:
    s = spec(cron='*/15 * * * *')
    assert latest_fire_at_or_before(s, T0 + 900, T0 + 3600 + 7 * 60) == (T0 + 3600, 4)
    assert latest_fire_at_or_before(s, T0 + 900, T0 + 900) == (T0 + 900, 1)


def test_a_cron_count_beyond_the_limit_is_a_lower_bound_with_the_right_latest_time() -> None:
    s = spec(cron='* * * * *')
    now = T0 + 30 * 86400 + 30  # 43,201 minutes in [T0, now]
    assert latest_fire_at_or_before(s, T0, now) == (T0 + 30 * 86400, CRON_COUNT_LIMIT)


def test_a_one_shot_has_one_time_to_catch_up() -> None:
    assert latest_fire_at_or_before(spec(at=T0), T0, T0 + 1e6) == (T0, 1)


# ---- description and storage -------------------------------------------------------------


def test_describe_says_when_it_fires() -> None:
    assert request(at='2026-11-25T02:00:00Z').describe() == 'once at 2026-11-25T02:00:00+00:00'
    assert request(period_sec=7200).describe() == 'every 7200 s'
    assert request(period_sec=1.5).describe() == 'every 1.5 s'
    assert request(cron='0  2 * * *', time_zone='Europe/Paris').describe() == (
        "cron '0 2 * * *' (Europe/Paris)"
    )
    windowed = request(period_sec=60, end='2026-02-01T00:00:00Z', max_runs=3)
    assert windowed.describe() == 'every 60 s, until 2026-02-01T00:00:00+00:00, at most 3 runs'


NUMBERS = st.floats(min_value=0, max_value=4e9, allow_nan=False)
COMMON = st.fixed_dictionaries(
    {
        'schedule_id': st.from_regex(r'[A-Za-z0-9_.:-]{1,64}', fullmatch=True),
        'task_name': st.text(),
        'task_data': st.text(),
        'created_by': st.text(),
        'created': NUMBERS,
        'time_zone': st.sampled_from(['UTC', 'Europe/Paris', 'America/New_York']),
        'start': st.none() | NUMBERS,
        'end': st.none() | NUMBERS,
        'max_runs': st.integers(0, 2**31 - 1),
        'overlap': st.sampled_from(OverlapPolicy),
        'misfire_grace_sec': st.floats(min_value=0, max_value=604_800),
    }
)
WHEN = st.one_of(
    st.fixed_dictionaries({'at': NUMBERS}),
    st.fixed_dictionaries({'period_sec': st.floats(0.1, 366 * 24 * 3600.0)}),
    st.fixed_dictionaries({'cron': st.sampled_from(['0 2 * * *', '*/15 * * * *', '0 8 * * 1-5'])}),
)
SPECS = st.builds(lambda common, when: ScheduleSpec(**common, **when), COMMON, WHEN)


@given(SPECS)
def test_a_spec_round_trips_through_json_exactly(s: ScheduleSpec) -> None:
    assert ScheduleSpec.from_json(s.to_json()) == s


@pytest.mark.parametrize(
    ('change', 'message'),
    [
        (lambda d: d.update(colour='red'), r"unexpected fields \['colour'\]"),
        (lambda d: d.pop('cron'), r"missing fields \['cron'\]"),
        (lambda d: d.update(created='yesterday'), r'created has a value of the wrong type'),
        (lambda d: d.update(max_runs=True), r'max_runs has a value of the wrong type'),
        (lambda d: d.update(max_runs=1.5), r'max_runs has a value of the wrong type'),
        (lambda d: d.update(start=float('inf')), r'start is not a finite number'),
        (lambda d: d.update(overlap='SOMETIMES'), r"'SOMETIMES' is not a valid OverlapPolicy"),
        (lambda d: d.update(time_zone='Mars/Olympus'), r'is not a known time zone'),
        (lambda d: d.update(cron='61 * * * *'), r'is not a cron expression'),
        (lambda d: d.update(period_sec=60.0), r'exactly one of at, period_sec, cron; got 2'),
    ],
)
def test_a_stored_spec_this_version_cannot_run_is_refused(
    change: Callable[[dict[str, Any]], object], message: str
) -> None:
    data = json.loads(spec(cron='0 2 * * *').to_json())
    change(data)
    with pytest.raises(ValueError, match=message):
        ScheduleSpec.from_json(json.dumps(data))


@pytest.mark.parametrize('text', ['', 'not json', '[1, 2]', '"text"'])
def test_stored_text_that_is_no_json_object_is_refused(text: str) -> None:
    with pytest.raises(ValueError):
        ScheduleSpec.from_json(text)
