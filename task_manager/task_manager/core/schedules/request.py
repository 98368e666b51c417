"""A schedule request's fields, checked and turned into a ScheduleSpec (system/schedule).

Every refusal is a ScheduleError naming the field, what is wrong and what is allowed.
"""

import math
import re
from collections.abc import Callable, Mapping
from datetime import datetime
from typing import Any
from zoneinfo import ZoneInfo

from task_manager.core.admission.options import RequestOptions
from task_manager.core.bounds import DELAY_SECONDS
from task_manager.core.schedules.schedule import (
    DEFAULT_MISFIRE_GRACE_SEC,
    MIN_PERIOD_SEC,
    OverlapPolicy,
    ScheduleError,
    ScheduleSpec,
    check_bounds,
    check_cron,
    first_fire_time,
    in_window,
    iso_text,
    number_text,
    zone_of,
)

_ID_PATTERN = re.compile(r'[A-Za-z0-9_.:-]{1,64}')
_WHEN_FIELDS = ('at', 'delay_sec', 'period_sec', 'cron')


def parse_schedule_request(
    fields: Mapping[str, Any], created_by: str, now: float, new_id: Callable[[], str]
) -> ScheduleSpec:
    """The schedule a request asks for; ScheduleError says what is wrong and what is allowed.

    Missing fields take their defaults; `new_id` names a schedule requested without an id.
    """
    schedule_id = _text(fields, 'schedule_id') or new_id()
    if not _ID_PATTERN.fullmatch(schedule_id):
        raise ScheduleError(
            'schedule_id',
            f"schedule_id '{schedule_id}' is not allowed: use 1 to 64 characters among "
            'A-Z a-z 0-9 _ . : - (it becomes part of task ids and topic names)',
        )
    task_name = _text(fields, 'task_name')
    if not task_name.strip():
        raise ScheduleError('task_name', 'task_name is required: the task or mission to run')
    time_zone = _text(fields, 'time_zone') or 'UTC'
    zone = zone_of('time_zone', time_zone)
    grace = _number_field(fields, 'misfire_grace_sec', DEFAULT_MISFIRE_GRACE_SEC)
    spec = ScheduleSpec(
        schedule_id=schedule_id,
        task_name=task_name,
        task_data=_text(fields, 'task_data'),
        created_by=created_by,
        created=now,
        **_when(fields, now),
        time_zone=time_zone,
        start=_instant(fields, 'start'),
        end=_instant(fields, 'end'),
        max_runs=_max_runs(fields),
        overlap=_overlap(_text(fields, 'overlap')),
        misfire_grace_sec=grace if grace >= 0 else DEFAULT_MISFIRE_GRACE_SEC,
        options=_options(fields),
    )
    check_bounds(spec)
    _check_window(spec, now, zone)
    return spec


def _options(fields: Mapping[str, Any]) -> dict[str, Any]:
    """How each run is admitted: the request's options, checked (none: the declaration's)."""
    options = fields.get('options') or RequestOptions()
    if problem := options.problem():
        raise ScheduleError('options', f'options: {problem}')
    return options.to_dict()


def _when(fields: Mapping[str, Any], now: float) -> dict[str, Any]:
    """The at / period_sec / cron fields of the spec; exactly one of the four must be given."""
    at_text, cron = _text(fields, 'at').strip(), _text(fields, 'cron').strip()
    delay, period = _number_field(fields, 'delay_sec', 0), _number_field(fields, 'period_sec', 0)
    values = (at_text, delay, period, cron)
    given = [name for name, value in zip(_WHEN_FIELDS, values, strict=True) if value]
    if len(given) != 1:
        got = ' and '.join(given) if given else 'none'
        raise ScheduleError(
            ','.join(given or _WHEN_FIELDS),
            f'give exactly one of at, delay_sec, period_sec, cron; got {got}',
        )
    if delay < 0:
        raise ScheduleError(
            'delay_sec', f'delay_sec must be more than 0 s, got {number_text(delay)}'
        )
    if problem := DELAY_SECONDS.problem('delay_sec', delay):
        raise ScheduleError('delay_sec', problem)
    if period and period < MIN_PERIOD_SEC:
        raise ScheduleError(
            'period_sec',
            f'period_sec must be at least {MIN_PERIOD_SEC} s, got {number_text(period)}',
        )
    if at_text:
        return {'at': _instant(fields, 'at')}
    if delay:
        return {'at': now + delay}
    if period:
        return {'period_sec': period}
    check_cron(cron)
    return {'cron': ' '.join(cron.split())}


def _check_window(spec: ScheduleSpec, now: float, zone: ZoneInfo) -> None:
    """Refuse a window that is empty or a schedule that can never run."""
    if spec.start is not None and spec.end is not None and spec.end <= spec.start:
        raise ScheduleError(
            'end',
            f'end {iso_text(spec.end, zone)} must be after start {iso_text(spec.start, zone)}',
        )
    if spec.at is not None:
        if not in_window(spec, spec.at):
            start, end = (
                iso_text(t, zone) if t is not None else '-' for t in (spec.start, spec.end)
            )
            raise ScheduleError(
                'at', f'at {iso_text(spec.at, zone)} is outside the window from start {start} to '
                f'end {end}: give an at within it'
            )  # fmt: skip
        if spec.at < now - spec.misfire_grace_sec:
            raise ScheduleError(
                'at', f'at {iso_text(spec.at, zone)} is in the past (more than misfire_grace_sec '
                f'{number_text(spec.misfire_grace_sec)} s ago); give a future time'
            )  # fmt: skip
    elif first_fire_time(spec) is None:
        field = 'cron' if spec.end is None else 'end'
        until = '' if spec.end is None else f' before end {iso_text(spec.end, zone)}'
        raise ScheduleError(field, f'the schedule has no fire time{until}: it would never run')


def _overlap(text: str) -> OverlapPolicy:
    try:
        return OverlapPolicy(text.upper()) if text else OverlapPolicy.SKIP
    except ValueError:
        names = ', '.join(OverlapPolicy)
        raise ScheduleError(
            'overlap', f"overlap '{text}' is not an overlap policy; use one of {names} "
            "('' is SKIP)"
        ) from None  # fmt: skip


def _max_runs(fields: Mapping[str, Any]) -> int:
    value = fields.get('max_runs', 0)
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ScheduleError('max_runs', f'max_runs must be 0 (unlimited) or more, got {value!r}')
    return value


def _instant(fields: Mapping[str, Any], field: str) -> float | None:
    """An ISO 8601 time with a zone as epoch seconds; None for ''."""
    text = _text(fields, field).strip()
    if not text:
        return None
    try:
        moment = datetime.fromisoformat(text)
    except ValueError:
        raise ScheduleError(
            field, f"{field} '{text}' is not an ISO 8601 time; use e.g. "
            "'2026-11-25T02:00:00+01:00' or '2026-11-25T01:00:00Z'"
        ) from None  # fmt: skip
    if moment.tzinfo is None:
        raise ScheduleError(
            field, f"{field} '{text}' has no zone; a zone offset is required, e.g. "
            f"'{text}+01:00' or '{text}Z'"
        )  # fmt: skip
    return moment.timestamp()


def _text(fields: Mapping[str, Any], field: str) -> str:
    value = fields.get(field, '')
    if not isinstance(value, str):
        raise ScheduleError(field, f'{field} must be text, got {type(value).__name__}')
    return value


def _number_field(fields: Mapping[str, Any], field: str, default: float) -> float:
    value = fields.get(field, default)
    if isinstance(value, bool) or not isinstance(value, float | int) or not math.isfinite(value):
        raise ScheduleError(field, f'{field} must be a finite number of seconds, got {value!r}')
    return float(value)
