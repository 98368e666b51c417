"""The fleet console at scale: 200 simulated robots (no ROS, each its own MQTT connection and
broker account) against `task-manager-console` as users start it, on a local mosquitto, with
the fleet history on SQLite and on PostgreSQL.

For each database:
- ingest: the robots run one task after another, each task three messages as a bridge sends
  them (active_tasks with it running, active_tasks without it, its result), about
  EVENTS_OFFERED_PER_SEC messages a second in all for LOAD_SEC; ingested per second = every
  message sent over the time from the first sent to the last result seen stored (each robot's
  last message is a result, and the console reads a connection's messages in order); a
  result's lag is from its end (stamped by the robot as it sends it) to its row's stored_at
  (stamped as its transaction begins);
- a backlog: the console stopped, the robots send BACKLOG_TASKS tasks each, the console started
  again: results stored per second from its first row to its last;
- GET /api/robots, every robot holding three active tasks;
- the history filled to HISTORY_ROWS results (a bulk insert, not through the broker), then
  GET /api/history with each filter of the page, and two together.
The console's own CPU (psutil) is noted for each load; a py-spy profile of it ingesting is
printed with the others (unless --no-profile).
"""

import time
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime, timedelta

import psutil

from bench.fleet.load import PacedLoad, fill, lags_sec, last_id, stored_span_sec, wait_rows
from bench.fleet.running import DATABASES, TASKS, RunningFleet, running_fleet
from bench.harness.context import BenchContext
from bench.harness.profiler import PySpyRecorder
from bench.harness.replies import BenchError
from bench.harness.report import Row
from bench.harness.stats import Summary

ROBOTS = 200
EVENTS_TARGET_PER_SEC = 5000
EVENTS_OFFERED_PER_SEC = 5500
"""Offered a tenth above the target, so that keeping up with it shows the target met."""
LOAD_SEC = 20.0
PROFILE_SEC = 8.0
LAG_TARGET_SEC = 1.0
QUERY_TARGET_MS = 50.0
BACKLOG_TASKS = 100
"""Tasks each robot ends while the console is stopped (20,000 results, 60,000 messages)."""
HISTORY_ROWS = 1_000_000
ROBOTS_SAMPLES = 100
HISTORY_SAMPLES = 40
"""Per filter of the history."""
DRAIN_TIMEOUT_SEC = 180.0


def run(ctx: BenchContext) -> None:
    for database in DATABASES:
        print(f'[bench] console on {database} ...', flush=True)
        with running_fleet(ctx.log_dir, database, ROBOTS) as fleet:
            _ingest(ctx, fleet)
            _backlog(ctx, fleet)
            _robots(ctx, fleet)
            _history(ctx, fleet)
            if ctx.profiling:
                _profile(ctx, fleet)


@contextmanager
def _cpu_sec(pid: int | None) -> Iterator[list[float]]:
    """The CPU seconds (user + system) process `pid` (None: this one) uses in the body, in
    [0] after it."""
    process = psutil.Process(pid)
    used = [0.0]
    before = process.cpu_times()
    yield used
    after = process.cpu_times()
    used[0] = after.user + after.system - before.user - before.system


def _ingest(ctx: BenchContext, fleet: RunningFleet) -> None:
    before = last_id(fleet.history)
    load = PacedLoad.lasting(fleet.robots, EVENTS_OFFERED_PER_SEC, LOAD_SEC)
    with _cpu_sec(fleet.console.process.pid) as console_sec, _cpu_sec(None) as robots_sec:
        load.run(LOAD_SEC * 3)
        seen = wait_rows(fleet.history, before, load.results, DRAIN_TIMEOUT_SEC)
    elapsed = seen - load.started_at
    ingested = load.events / elapsed
    lag = Summary.of(lags_sec(fleet.history, before))
    name = f'console ingest, {fleet.database}'
    ctx.report.add(
        Row(
            benchmark=name,
            metric=f'events/s ingested, {ROBOTS} robots, {load.events:,} sent (1/3 results)',
            measured=f'{ingested:,.0f}/s',
            baseline=f'{load.offered_per_sec:,.0f}/s offered',
            target=f'>= {EVENTS_TARGET_PER_SEC:,}/s',
            met=ingested >= EVENTS_TARGET_PER_SEC,
        ),
        Row(
            benchmark=name,
            metric=f'results stored/s; lag s from result to row, med / p95, n={lag.count:,}',
            measured=f'{load.results / elapsed:,.0f}/s; {lag.text()} s',
            baseline='',
            target=f'lag p95 <= {LAG_TARGET_SEC:.0f} s',
            met=lag.p95 <= LAG_TARGET_SEC,
        ),
    )
    ctx.report.note(
        f'{name}: the console used {console_sec[0] / elapsed:.2f} cores '
        f'({console_sec[0] * 1e6 / load.events:.0f} us of CPU per message), the simulated robots '
        f'and the bench {robots_sec[0] / elapsed:.2f}'
    )


def _backlog(ctx: BenchContext, fleet: RunningFleet) -> None:
    fleet.console.stop()
    before = last_id(fleet.history)
    load = PacedLoad(fleet.robots, float('inf'), BACKLOG_TASKS)
    load.run(DRAIN_TIMEOUT_SEC)
    for robot in fleet.robots:  # all with the broker before the console is back
        robot.wait_taken(robot.published, DRAIN_TIMEOUT_SEC)
    fleet.restart_console()
    started = time.monotonic()
    with _cpu_sec(fleet.console.process.pid) as console_sec:
        seen = wait_rows(fleet.history, before, load.results, DRAIN_TIMEOUT_SEC)
    stored = stored_span_sec(fleet.history, before)
    ctx.report.add(
        Row(
            benchmark=f'console backlog, {fleet.database}',
            metric=f'{load.results:,} results ({load.events:,} messages) waiting: stored/s',
            measured=f'{load.results / stored:,.0f}/s',
            baseline=f'{load.events / stored:,.0f} messages/s',
            ratio=f'{seen - started:.1f} s from ready',
        )
    )
    ctx.report.note(
        f'console backlog, {fleet.database}: {console_sec[0] * 1e6 / load.events:.0f} us of '
        "the console's CPU per message"
    )


def _robots(ctx: BenchContext, fleet: RunningFleet) -> None:
    for robot in fleet.robots:
        running = robot.running(f'{robot.robot_id}-busy', TASKS[0])
        queued = [
            {**robot.running(f'{robot.robot_id}-next-{n}', TASKS[n]), 'status': 'QUEUED',
             'started': None, 'queue_position': n}
            for n in (1, 2)
        ]  # fmt: skip
        robot.set_active([running, *queued])
    samples = [_get_ms(fleet, '/api/robots', {}) for _ in range(ROBOTS_SAMPLES)]
    listed = fleet.robots_listed()
    if len(listed) != ROBOTS or any(len(r['active']) != 3 for r in listed):
        raise BenchError(f'GET /api/robots: not {ROBOTS} robots with 3 active tasks each')
    metric = f'GET /api/robots ms, {ROBOTS} robots, 3 active tasks each'
    ctx.report.add(_latency_row(f'console robots, {fleet.database}', metric, samples))


def _history(ctx: BenchContext, fleet: RunningFleet) -> None:
    fill_sec = fill(fleet.history, [r.robot_id for r in fleet.robots], HISTORY_ROWS, TASKS)
    middle = datetime.now(UTC) - timedelta(days=15)
    filters = {
        'newest': {},
        'robot': {'robot_id': 'robot042'},
        'task name': {'task_name': TASKS[1]},
        'status': {'status': 'ERROR'},
        'source': {'source': 'WEB:bob'},
        'an hour': {
            'ended_after': middle.isoformat(),
            'ended_before': (middle + timedelta(hours=1)).isoformat(),
        },
        'robot and status': {'robot_id': 'robot042', 'status': 'CANCELED'},
        'task id': {'task_id': 'fill-123456'},
    }
    per_filter = {
        name: [_get_ms(fleet, '/api/history', parameters) for _ in range(HISTORY_SAMPLES)]
        for name, parameters in filters.items()
    }
    metric = f'GET /api/history ms (100 rows), {HISTORY_ROWS:,} stored, {len(filters)} filters'
    every = [sample for samples in per_filter.values() for sample in samples]
    ctx.report.add(_latency_row(f'console history, {fleet.database}', metric, every))
    ctx.report.note(
        f'console history, {fleet.database}: filled to {HISTORY_ROWS:,} rows in {fill_sec:.0f} s; '
        'med / p95 ms by filter: '
        + ', '.join(f'{name} {Summary.of(s).text(1)}' for name, s in per_filter.items())
    )


def _get_ms(fleet: RunningFleet, path: str, parameters: dict[str, str]) -> float:
    """One GET of the console's, in ms; it must answer 200."""
    started = time.perf_counter()
    answer = fleet.http.get(path, params=parameters)
    elapsed_ms = (time.perf_counter() - started) * 1000
    if answer.status_code != 200:
        raise BenchError(f'GET {path} {parameters}: {answer.status_code} {answer.text[:200]}')
    return elapsed_ms


def _latency_row(benchmark: str, metric: str, samples: list[float]) -> Row:
    summary = Summary.of(samples)
    return Row(
        benchmark=benchmark,
        metric=f'{metric}, med / p95, n={summary.count}',
        measured=summary.text(1),
        baseline='',
        target=f'p95 <= {QUERY_TARGET_MS:.0f} ms',
        met=summary.p95 <= QUERY_TARGET_MS,
    )


def _profile(ctx: BenchContext, fleet: RunningFleet) -> None:
    """py-spy on the console while it ingests (after the measures: sampling slows it)."""
    title = f'the console, ingesting {EVENTS_OFFERED_PER_SEC:,} messages/s on {fleet.database}'
    recorder = PySpyRecorder(ctx.log_dir / f'profile_console_{fleet.database}.txt')
    load = PacedLoad.lasting(fleet.robots, EVENTS_OFFERED_PER_SEC, PROFILE_SEC)
    before = last_id(fleet.history)
    with recorder.recording(fleet.console.process.pid):
        load.run(PROFILE_SEC * 3)
        wait_rows(fleet.history, before, load.results, DRAIN_TIMEOUT_SEC)
    profile = recorder.profile()
    if profile is None:
        ctx.report.note(f'no profile of {title}: {recorder.failure}')
    else:
        ctx.profiles[title] = profile
