"""What a schedule is and when it fires: once at a time, every period, or on a cron expression.

A schedule starts a task (or mission) with its data at its fire times, within an optional
start..end window. Every time is an epoch float; cron times are computed in the schedule's
IANA time zone. Pure: the caller passes `now`, so everything is tested with a clock it sets.
"""

import dataclasses
import functools
import json
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from enum import StrEnum
from typing import Any
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

from task_manager.core.admission.options import RequestOptions
from task_manager.core.bounds import (
    COUNT,
    EPOCH_SECONDS,
    PERIOD_SECONDS,
    SECONDS,
    TASK_DATA_MAX_BYTES,
    NumberBound,
)

# A robot reboot plus ROS bring-up takes a few minutes: a nightly 02:00 mission that starts at
# 02:10 is still the night's mission, while one that starts hours late, when people are around,
# must not. 15 minutes covers the first and refuses the second.
DEFAULT_MISFIRE_GRACE_SEC = 900.0

# Counting the cron times missed over a long downtime walks them one by one (croniter has no
# arithmetic); past this many the count is a lower bound, so a catch-up never stalls the node.
CRON_COUNT_LIMIT = 10_000

MIN_PERIOD_SEC = PERIOD_SECONDS.low

_CRON_HELP = "5 fields: minute hour day-of-month month day-of-week, e.g. '0 2 * * *'"
# Steps past local times that a fixed-hour cron skips on a DST fall-back night (at most hours).
_CRON_STEP_LIMIT = 1_000


class ScheduleError(ValueError):
    """A schedule request that cannot be accepted; `field` names the request field at fault.

    For "give exactly one of at, delay_sec, period_sec, cron", `field` lists the fields given
    (or all four when none was), joined by ','.
    """

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field


class OverlapPolicy(StrEnum):
    """What a firing does while the previous run of the same schedule is still active.

    Named after Temporal's schedule overlap policies.
    """

    SKIP = 'SKIP'
    """The firing is skipped (counted); the default."""
    BUFFER_ONE = 'BUFFER_ONE'
    """The firing runs right after the previous run ends; more firings meanwhile are skipped."""
    CANCEL_OTHER = 'CANCEL_OTHER'
    """The previous run is cancelled, then the firing starts."""
    ALLOW_ALL = 'ALLOW_ALL'
    """The firing starts regardless; only for reentrant tasks."""


class ScheduleKind(StrEnum):
    """How a schedule's fire times are given."""

    AT = 'at'
    PERIOD = 'period'
    CRON = 'cron'


@dataclass(frozen=True)
class ScheduleSpec:
    """A schedule as requested; never changes (its run state is a ScheduleState)."""

    schedule_id: str
    task_name: str
    task_data: str
    """JSON object text, kept as given (the caller checks it against the task)."""
    created_by: str
    """The source of the request."""
    created: float
    at: float | None = None
    """A one-shot's time (from `at`, or created + delay_sec)."""
    period_sec: float = 0.0
    """0: not periodic."""
    cron: str = ''
    time_zone: str = 'UTC'
    """IANA name; the zone of cron times (and of describe())."""
    start: float | None = None
    end: float | None = None
    max_runs: int = 0
    """0: unlimited."""
    overlap: OverlapPolicy = OverlapPolicy.SKIP
    misfire_grace_sec: float = DEFAULT_MISFIRE_GRACE_SEC
    options: dict[str, Any] = field(default_factory=dict, hash=False)
    """How each run is admitted (RequestOptions.to_dict: priority, on_conflict, timeouts)."""

    def __post_init__(self) -> None:
        given = (self.at is not None) + (self.period_sec > 0) + bool(self.cron)
        if given != 1:
            raise ValueError(f'a schedule has exactly one of at, period_sec, cron; got {given}')

    @property
    def kind(self) -> ScheduleKind:
        if self.at is not None:
            return ScheduleKind.AT
        return ScheduleKind.PERIOD if self.period_sec > 0 else ScheduleKind.CRON

    def describe(self) -> str:
        """A human description of when it fires, e.g. "cron '0 2 * * *' (Europe/Paris)"."""
        zone = ZoneInfo(self.time_zone)
        if self.at is not None:
            text = f'once at {iso_text(self.at, zone)}'
        elif self.period_sec > 0:
            text = f'every {number_text(self.period_sec)} s'
        else:
            text = f"cron '{self.cron}' ({self.time_zone})"
        if self.start is not None:
            text += f', from {iso_text(self.start, zone)}'
        if self.end is not None:
            text += f', until {iso_text(self.end, zone)}'
        if self.max_runs:
            text += f', at most {self.max_runs} runs'
        return text

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), separators=(',', ':'))

    @classmethod
    def from_json(cls, text: str) -> 'ScheduleSpec':
        """The spec stored by to_json; ValueError if it is not one this version can run (a
        ScheduleError naming the field for one outside the bounds, e.g. an older version's)."""
        values = load_fields(_with_options(text), _SPEC_TYPES)
        values['overlap'] = OverlapPolicy(values['overlap'])
        spec = cls(**values)
        zone_of('time_zone', spec.time_zone)
        if spec.cron:
            check_cron(spec.cron)
        check_bounds(spec)
        return spec


def check_bounds(spec: ScheduleSpec) -> None:
    """Raise ScheduleError naming the first field of `spec` outside its bound (core/bounds.py):
    the same check for a request and for a schedule read back from the history file."""
    numbers: list[tuple[str, NumberBound, float | None]] = [
        ('created', EPOCH_SECONDS, spec.created),
        ('at', EPOCH_SECONDS, spec.at),
        ('start', EPOCH_SECONDS, spec.start),
        ('end', EPOCH_SECONDS, spec.end),
        ('period_sec', PERIOD_SECONDS, spec.period_sec or None),
        ('misfire_grace_sec', SECONDS, spec.misfire_grace_sec),
        ('max_runs', COUNT, spec.max_runs),
    ]
    for name, bound, value in numbers:
        if value is not None and (problem := bound.problem(name, value)):
            raise ScheduleError(name, problem)
    if (size := len(spec.task_data.encode())) > TASK_DATA_MAX_BYTES:
        raise ScheduleError(
            'task_data', f'task_data is {size} bytes; at most {TASK_DATA_MAX_BYTES} are allowed'
        )
    try:
        options = RequestOptions.from_dict(spec.options)
    except (TypeError, ValueError) as error:
        raise ScheduleError('options', f'options: {error}') from None
    if problem := options.problem():
        raise ScheduleError('options', f'options: {problem}')


_NUMBER = (float, int)
_OPTIONAL_NUMBER = (float, int, type(None))
# key: field, value: the JSON types it may hold (json.loads gives int for a float written as 1)
_SPEC_TYPES: dict[str, tuple[type, ...]] = {
    'schedule_id': (str,), 'task_name': (str,), 'task_data': (str,), 'created_by': (str,),
    'created': _NUMBER, 'at': _OPTIONAL_NUMBER, 'period_sec': _NUMBER, 'cron': (str,),
    'time_zone': (str,), 'start': _OPTIONAL_NUMBER, 'end': _OPTIONAL_NUMBER, 'max_runs': (int,),
    'overlap': (str,), 'misfire_grace_sec': _NUMBER, 'options': (dict,),
}  # fmt: skip


def _with_options(text: str) -> str:
    """A spec stored before schedules had options (schema 2) runs with none."""
    data = json.loads(text)
    if isinstance(data, dict) and 'options' not in data:
        data['options'] = {}
        return json.dumps(data)
    return text


def load_fields(text: str, types: Mapping[str, tuple[type, ...]]) -> dict[str, Any]:
    """The fields of a stored JSON object, exactly those of `types` and of those types.

    Raises ValueError otherwise (corrupt text, or a field from another version).
    """
    data = json.loads(text)
    if not isinstance(data, dict):
        raise ValueError(f'not a JSON object: {text[:80]}')
    if set(data) != set(types):
        unknown, missing = sorted(set(data) - set(types)), sorted(set(types) - set(data))
        raise ValueError(f'unexpected fields {unknown}, missing fields {missing}')
    for name, value in data.items():
        allowed = types[name]
        # bool is an int to isinstance, but never a number here
        if (isinstance(value, bool) and bool not in allowed) or not isinstance(value, allowed):
            raise ValueError(f'{name} has a value of the wrong type: {value!r}')
        if isinstance(value, float | int) and not isinstance(value, bool):
            if not math.isfinite(value):
                raise ValueError(f'{name} is not a finite number: {value!r}')
            if float in types[name]:
                data[name] = float(value)
    return data


def iso_text(t: float, zone: ZoneInfo) -> str:
    return datetime.fromtimestamp(t, zone).isoformat()


def number_text(value: float) -> str:
    return str(int(value)) if value.is_integer() else str(value)


# ---- fire times --------------------------------------------------------------------------


def first_fire_time(spec: ScheduleSpec) -> float | None:
    """The first due time, or None when the window holds none.

    A periodic schedule whose start is before its creation does not owe the runs from before
    it existed: it starts at the first period time after its creation.
    """
    if spec.kind is ScheduleKind.AT:
        assert spec.at is not None
        return spec.at if in_window(spec, spec.at) else None
    if spec.kind is ScheduleKind.PERIOD and _anchor(spec) >= spec.created:
        return _anchor(spec) if in_window(spec, _anchor(spec)) else None
    return next_fire_after(spec, spec.created)


def next_fire_after(spec: ScheduleSpec, after: float) -> float | None:
    """The first fire time strictly after `after` within the window; None when there is none."""
    if spec.kind is ScheduleKind.AT:
        assert spec.at is not None
        return spec.at if spec.at > after and in_window(spec, spec.at) else None
    t: float | None
    if spec.kind is ScheduleKind.PERIOD:
        t = _anchor(spec) + _index_after(spec, after) * spec.period_sec
    else:
        t = _cron_after(spec, after)
    return None if t is None or (spec.end is not None and t > spec.end) else t


def latest_fire_at_or_before(spec: ScheduleSpec, due: float, now: float) -> tuple[float, int]:
    """For a fire time `due <= now`: the latest fire time L in [due, now] and how many lie there.

    Periodic: arithmetic, exact. Cron: the count is exact up to CRON_COUNT_LIMIT and a lower
    bound beyond it. Times after the window's end are not counted.
    """
    upper = now if spec.end is None else min(now, spec.end)
    if spec.kind is ScheduleKind.AT or upper <= due:
        return due, 1
    if spec.kind is ScheduleKind.PERIOD:
        first, last = _index_at_or_after(spec, due), _index_at(spec, upper)
        return max(_anchor(spec) + last * spec.period_sec, due), max(last - first + 1, 1)
    latest, count = due, 1
    for t in _cron_times(spec, due):
        if t > upper:
            break
        if count == CRON_COUNT_LIMIT:
            return max(_cron_at_or_before(spec, upper), latest), count
        latest, count = t, count + 1
    return latest, count


def in_window(spec: ScheduleSpec, t: float) -> bool:
    return (spec.start is None or t >= spec.start) and (spec.end is None or t <= spec.end)


def _anchor(spec: ScheduleSpec) -> float:
    """Periodic times are anchor + k * period_sec, k >= 0."""
    return spec.start if spec.start is not None else spec.created + spec.period_sec


def _index_after(spec: ScheduleSpec, after: float) -> int:
    """The smallest k >= 0 whose periodic time is strictly after `after`."""
    anchor, period = _anchor(spec), spec.period_sec
    if after < anchor:
        return 0
    k = math.floor((after - anchor) / period) + 1
    # the division rounds: correct k by one step either way
    while anchor + k * period <= after:
        k += 1
    while k > 0 and anchor + (k - 1) * period > after:
        k -= 1
    return k


def _index_at_or_after(spec: ScheduleSpec, t: float) -> int:
    """The smallest k >= 0 whose periodic time is at or after `t`."""
    k = _index_after(spec, t)
    return k - 1 if k > 0 and _anchor(spec) + (k - 1) * spec.period_sec >= t else k


def _index_at(spec: ScheduleSpec, t: float) -> int:
    """The largest k >= 0 whose periodic time is at or before `t` (0 when none is)."""
    return max(_index_after(spec, t) - 1, 0)


def _cron_iterator(spec: ScheduleSpec, base: float) -> Any:
    # croniter (and dateutil) is imported on first use: 45 ms of CPU at the start of every
    # process that imports this module (the node, taskctl, the gateways), most of which
    # never meet a cron schedule
    from croniter import croniter  # type: ignore[import-untyped]

    return croniter(spec.cron, datetime.fromtimestamp(base, ZoneInfo(spec.time_zone)))


def _repeats_in_fall_back(expression: str) -> bool:
    """Whether a cron job runs in both passes of a local hour repeated by a DST fall-back.

    As in Vixie cron: jobs with '*' in the minute or hour field run by the elapsed time (both
    passes); fixed-time jobs run once per local time, so '0 2 * * *' runs once that night.
    """
    minute, hour = expression.split()[:2]
    return minute.startswith('*') or hour.startswith('*')


def _cron_times(spec: ScheduleSpec, after: float) -> Iterator[float]:
    """The cron times strictly after `after` (no window), in order; ends if none is left."""
    from croniter import CroniterBadDateError

    iterator = _cron_iterator(spec, after)
    zone, repeats = ZoneInfo(spec.time_zone), _repeats_in_fall_back(spec.cron)
    skipped = 0
    while skipped < _CRON_STEP_LIMIT:
        try:
            t = float(iterator.get_next(float))
        except CroniterBadDateError:  # no time in the next 50 years (e.g. 30 February)
            return
        if repeats or not datetime.fromtimestamp(t, zone).fold:
            skipped = 0
            yield t
        else:
            skipped += 1


def _cron_after(spec: ScheduleSpec, after: float) -> float | None:
    # start itself may be a fire time: search from just before it (cron times are minutes)
    base = after if spec.start is None or spec.start <= after else spec.start - 1.0
    for t in _cron_times(spec, base):
        if spec.start is None or t >= spec.start:
            return t
    return None


def _cron_at_or_before(spec: ScheduleSpec, t: float) -> float:
    """The latest cron time at or before `t` (-inf if none), walking back from `t`."""
    from croniter import CroniterBadDateError

    iterator = _cron_iterator(spec, math.floor(t) + 1.0)
    zone, repeats = ZoneInfo(spec.time_zone), _repeats_in_fall_back(spec.cron)
    for _ in range(_CRON_STEP_LIMIT):
        try:
            previous = float(iterator.get_prev(float))
        except CroniterBadDateError:
            break
        if previous <= t and (repeats or not datetime.fromtimestamp(previous, zone).fold):
            return previous
    return -math.inf


# ---- requests ----------------------------------------------------------------------------


def check_cron(expression: str) -> None:
    reason = _cron_problem(expression)
    if reason:
        raise ScheduleError(
            'cron', f"cron '{expression}' is not a cron expression ({_CRON_HELP}): {reason}"
        )


@functools.lru_cache(maxsize=1024)
def _cron_problem(expression: str) -> str:
    """Why `expression` is not a 5-field cron expression ('' if it is); cached, as a node
    loading 10,000 stored schedules checks the same few expressions again and again."""
    from croniter import CroniterError, croniter

    if len(expression.split()) != 5:
        return f'it has {len(expression.split())} fields'
    try:
        croniter(expression, 0.0)
    except CroniterError as error:
        return str(error)
    return ''


def zone_of(field: str, name: str) -> ZoneInfo:
    try:
        return ZoneInfo(name)
    except (ZoneInfoNotFoundError, ValueError):  # ValueError: not a zone key ('../x', '/etc')
        raise ScheduleError(
            field, f"{field} '{name}' is not a known time zone; use an IANA name such as "
            "'UTC' or 'Europe/Paris'"
        ) from None  # fmt: skip
