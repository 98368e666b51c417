"""Per-task statistics and taskctl's spans of time, without ROS."""

from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import pytest

from task_manager.cli.durations import parse_span
from task_manager.core.history.stats import median, percentile, task_stats
from task_manager.core.status import TaskStatus

T0 = datetime(2026, 1, 1, tzinfo=UTC)


@dataclass(frozen=True)
class Ended:
    task_name: str
    status: TaskStatus
    started_at: datetime | None
    ended_at: datetime | None
    paused: timedelta = timedelta(0)


def _ran(name: str, seconds: float | None, status: TaskStatus = TaskStatus.DONE) -> Ended:
    if seconds is None:  # refused: never started
        return Ended(name, status, None, T0)
    return Ended(name, status, T0, T0 + timedelta(seconds=seconds))


@pytest.mark.parametrize(
    ('text', 'seconds'),
    [('45s', 45), ('30m', 1800), ('2h', 7200), ('1d', 86400), ('1w', 604800),
     ('1h30m', 5400), ('1.5h', 5400), (' 2H ', 7200), ('0s', 0)],
)  # fmt: skip
def test_spans_of_time(text: str, seconds: float) -> None:
    assert parse_span(text) == timedelta(seconds=seconds)


@pytest.mark.parametrize('text', ['', '2', 'h', '2x', '-1h', '2 h', '1h-', 'yesterday'])
def test_a_bad_span_says_what_is_allowed(text: str) -> None:
    with pytest.raises(ValueError, match=r'not a span of time; use a number and a unit'):
        parse_span(text)


def test_stats_per_task_name_count_success_rate_median_and_p95() -> None:
    tasks = [
        *(_ran('nav', s) for s in (1, 2, 3, 4)),
        _ran('nav', 100, TaskStatus.ERROR),
        _ran('nav', None, TaskStatus.ERROR),  # counted, no duration
        _ran('cam', 0.5, TaskStatus.CANCELED),
    ]

    cam, nav = task_stats(tasks)

    assert (nav.task_name, nav.count, nav.done_count, nav.started_count) == ('nav', 6, 4, 5)
    assert nav.success_rate == pytest.approx(4 / 6)
    assert nav.median_duration == timedelta(seconds=3)
    assert nav.p95_duration == timedelta(seconds=100)
    assert (cam.task_name, cam.count, cam.success_rate) == ('cam', 1, 0.0)
    assert cam.median_duration == cam.p95_duration == timedelta(seconds=0.5)


def test_tasks_that_never_started_have_no_durations() -> None:
    (only,) = task_stats([_ran('x', None, TaskStatus.ERROR)])
    assert (only.count, only.started_count, only.median_duration, only.p95_duration) == (
        1, 0, None, None,
    )  # fmt: skip
    assert task_stats([]) == []


def test_time_paused_is_not_running_time() -> None:
    paused = Ended('nav', TaskStatus.DONE, T0, T0 + timedelta(seconds=10), timedelta(seconds=7))
    long_pause = Ended('nav', TaskStatus.DONE, T0, T0 + timedelta(seconds=1), timedelta(hours=1))

    (nav,) = task_stats([paused, long_pause, _ran('nav', 5)])

    assert nav.started_count == 3
    assert nav.median_duration == timedelta(seconds=3)  # of 0 s, 3 s and 5 s
    assert nav.p95_duration == timedelta(seconds=5)


def test_median_and_nearest_rank_percentile() -> None:
    values = [timedelta(seconds=s) for s in range(1, 21)]  # 1..20 s
    assert median(values) == timedelta(seconds=10.5)
    assert median(values[:3]) == timedelta(seconds=2)
    assert percentile(values, 0.95) == timedelta(seconds=19)
    assert percentile(values, 1.0) == timedelta(seconds=20)
    assert percentile(values[:1], 0.95) == timedelta(seconds=1)
    with pytest.raises(ValueError):
        percentile([], 0.5)
    with pytest.raises(ValueError):
        median([])
