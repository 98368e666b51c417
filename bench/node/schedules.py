"""Schedules (issue 15): the node's idle cost with many stored, and how late runs start.

1. Idle: the bench fills a new history file with STORED_SCHEDULES schedules (with the bursts',
   the most the node keeps: SCHEDULES_MAX) through the store's own code (half cron STORED_CRON
   in STORED_ZONE, half one-shots a year ahead: none fires during the bench), restarts the node
   on it and, after the pause the other idle measurement takes, measures its CPU over IDLE_SEC;
   the baseline is the same measurement with an empty store, just before (a restart of its
   own). The start-up of both (spawn to the "Task Manager ready" line, and to the first
   ExecuteTask reply) is reported too.
2. Lateness: with the stored schedules loaded, BURST_SCHEDULES one-shot schedules of the
   instant reentrant action task are created through ExecuteTask (system/schedule), due at
   T + i * BURST_SPACING_SEC with T BURST_LEAD_SEC after the first is sent. Once every run's
   result is on /task_manager/results, its `started` stamp (GetTaskStates) minus its due time
   is its lateness; its `received` stamp (when the node created the run's request) minus the
   due time is the scheduler's own part. BURST_ROUNDS bursts, new ids each; the samples of all
   bursts are pooled.
Finally the node is restarted with the default parameters.
"""

import json
import math
import os
import re
import statistics
import threading
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from bench.harness import config
from bench.harness.client import BenchClient, error_code, task_status
from bench.harness.context import BenchContext
from bench.harness.processes import start_node
from bench.harness.replies import BenchError, wait_reply
from bench.harness.report import Row
from bench.harness.stats import ratio, wait_all
from bench.harness.wake_ups import cpu_use
from bench.node.startup import READY_LINE
from task_manager.core.bounds import SCHEDULES_MAX
from task_manager.core.history.store import TaskHistory
from task_manager.core.names import GET_TASK_STATES_SERVICE, RESULTS_TOPIC
from task_manager.core.schedules.book import ScheduleState, run_task_id
from task_manager.core.schedules.schedule import ScheduleSpec, first_fire_time
from task_manager.rclpy_tools import qos
from task_manager_msgs.msg import TaskDoneResult
from task_manager_msgs.srv import GetTaskStates

SCHEDULE_TASK = 'system/schedule'
STORED_CRON = '0 3 1 1 *'
STORED_ZONE = 'Europe/Paris'
STORED_AT_AHEAD_SEC = 365 * 86400.0
IDLE_TARGET_PERCENT = 1.0

BURST_SCHEDULES = 100
BURST_SPACING_SEC = 0.010
# from sending the first system/schedule goal to the first due time: all are created before
BURST_LEAD_SEC = 3.0
BURST_ROUNDS = 3
# as many as the node keeps (SCHEDULES_MAX) with the bursts' (BURST_ROUNDS and one profiled):
# it refuses more
STORED_SCHEDULES = SCHEDULES_MAX - BURST_SCHEDULES * (BURST_ROUNDS + 1)
MEDIAN_TARGET_MS = 20.0
P99_TARGET_MS = 50.0
# beyond the last due time, how long the runs' results may take
RUNS_TIMEOUT_SEC = 30.0
RESULT_WARM_UP_ATTEMPTS = 5
RESULT_WARM_UP_TIMEOUT_SEC = 2.0
# psutil's CPU times count in these (USER_HZ, 100 on Linux)
TICKS_PER_SEC = os.sysconf('SC_CLK_TCK')
# the node's log line once its history file is open; the schedules are loaded after it
HISTORY_LINE = re.compile(r'\[(?P<stamp>\d+\.\d+)\] \[task_manager\]: task history: ')
LOADED_LINE = re.compile(r'\]: (?P<count>\d+) schedule\(s\) loaded')


def fill_schedules(path: Path, count: int) -> float:
    """Write `count` far-future schedules to a new history file; return the seconds it took."""
    started = time.perf_counter()
    now = time.time()
    history = TaskHistory(str(path))
    try:
        store = history.schedule_store()
        for index in range(count):
            common: dict[str, Any] = {
                'schedule_id': f'stored-{index}',
                'task_name': config.FIBONACCI_TASK,
                'task_data': config.FIBONACCI_DATA,
                'created_by': 'bench',
                'created': now,
            }
            if index % 2:
                spec = ScheduleSpec(**common, cron=STORED_CRON, time_zone=STORED_ZONE)
            else:
                spec = ScheduleSpec(**common, at=now + STORED_AT_AHEAD_SEC + index)
            store.save(spec, ScheduleState(next_run=first_fire_time(spec)))
    finally:
        history.close()
    return time.perf_counter() - started


def store_load_sec(path: Path) -> float:
    """Seconds ScheduleStore.load takes on the file, opened by the bench (as the node does)."""
    history = TaskHistory(str(path))
    try:
        started = time.perf_counter()
        loaded, unreadable = history.schedule_store().load()
        elapsed = time.perf_counter() - started
    finally:
        history.close()
    if len(loaded) != STORED_SCHEDULES or unreadable:
        raise BenchError(f'the store loaded {len(loaded)} schedules, {len(unreadable)} unreadable')
    return elapsed


@dataclass(frozen=True)
class Startup:
    """One start of the node, in ms."""

    replied_ms: float
    """From spawn to the first ExecuteTask reply (as startup.py measures it)."""
    ready_ms: float
    """From spawn to the "Task Manager ready" line."""
    loading_ms: float
    """From the "task history" line to the ready line: opening the schedules, mostly."""


def log_stamp(text: str, pattern: re.Pattern[str], what: str) -> float:
    """The stamp (wall clock, s) of the first log line `pattern` finds in `text`."""
    found = pattern.search(text)
    if found is None:
        raise BenchError(f'the node did not log {what}')
    return float(found['stamp'])


def restart_timed(ctx: BenchContext, name: str, **parameters: Any) -> Startup:
    """Restart the node (as ctx.restart_node), timing its start."""
    ctx.node.stop()
    params_file = config.write_node_params(ctx.log_dir, f'{name}_params', **parameters)
    spawned_at = time.time()
    started = time.perf_counter()
    ctx.node = start_node(params_file, ctx.log_dir, name)
    ctx.connect()
    replied_ms = (time.perf_counter() - started) * 1000
    log = ctx.node.log_path.read_text(errors='replace')
    ready_at = log_stamp(log, READY_LINE, '"Task Manager ready"')
    history_at = log_stamp(log, HISTORY_LINE, '"task history: ..."')
    return Startup(replied_ms, (ready_at - spawned_at) * 1000, (ready_at - history_at) * 1000)


def loaded_schedules(ctx: BenchContext) -> int:
    """How many schedules the node said it loaded at start (0 when it logged none)."""
    found = LOADED_LINE.search(ctx.node.log_path.read_text(errors='replace'))
    return int(found['count']) if found else 0


class ResultsWatcher:
    """Follows /task_manager/results: the status of every task id seen."""

    def __init__(self, client: BenchClient) -> None:
        self._changed = threading.Condition()
        # key: task id, value: its task_status
        self._statuses: dict[str, str] = {}
        self._node = client.harness.node
        self.subscription = self._node.create_subscription(
            TaskDoneResult, RESULTS_TOPIC, self._on_message, qos.RESULTS
        )

    def _on_message(self, message: Any) -> None:
        with self._changed:
            self._statuses[message.task_id] = message.task_status
            self._changed.notify_all()

    def wait_for(self, task_ids: list[str], timeout_sec: float, what: str) -> dict[str, str]:
        """The statuses of `task_ids` once all are in; BenchError after `timeout_sec`."""
        with self._changed:
            if not self._changed.wait_for(
                lambda: all(t in self._statuses for t in task_ids), timeout_sec
            ):
                missing = sum(1 for t in task_ids if t not in self._statuses)
                raise BenchError(
                    f'{what}: {missing} of {len(task_ids)} results not on {RESULTS_TOPIC} '
                    f'within {timeout_sec:.0f} s'
                )
            return {t: self._statuses[t] for t in task_ids}

    def destroy(self) -> None:
        self._node.destroy_subscription(self.subscription)


def warm_up_results(ctx: BenchContext, watcher: ResultsWatcher) -> None:
    """Run instant tasks until one's result reaches the watcher (its subscription matched)."""
    for attempt in range(RESULT_WARM_UP_ATTEMPTS):
        task_id = f'bench-schedules-warm-up-{attempt}'
        wait_reply(
            ctx.client.send_task(config.FIBONACCI_TASK, config.FIBONACCI_DATA, task_id), task_id
        )
        try:
            watcher.wait_for([task_id], RESULT_WARM_UP_TIMEOUT_SEC, task_id)
            return
        except BenchError:
            print(f'[bench] {RESULTS_TOPIC} warm-up {attempt + 1} not seen, retrying', flush=True)
    raise BenchError(f'no result seen on {RESULTS_TOPIC} in {RESULT_WARM_UP_ATTEMPTS} attempts')


def seconds(stamp: Any) -> float:
    return float(stamp.sec + stamp.nanosec * 1e-9)


def task_states(ctx: BenchContext, task_ids: list[str]) -> list[Any]:
    """The TaskState of each of `task_ids` (all must be known to the node)."""
    node = ctx.client.harness.node
    client: Any = node.create_client(
        GetTaskStates, GET_TASK_STATES_SERVICE, qos_profile=qos.DEEP_RELIABLE
    )
    try:
        if not client.wait_for_service(timeout_sec=config.CONNECT_TIMEOUT_SEC):
            raise BenchError(f'{GET_TASK_STATES_SERVICE} not available')
        reply = wait_reply(
            ctx.client.call(client, GetTaskStates.Request(task_ids=task_ids)), 'task states'
        )
    finally:
        node.destroy_client(client)
    states = list(reply.response.tasks)
    if len(states) != len(task_ids):
        raise BenchError(f'{GET_TASK_STATES_SERVICE}: {len(states)} of {len(task_ids)} tasks')
    return states


def schedule_data(schedule_id: str, at_text: str) -> str:
    return json.dumps(
        {
            'schedule_id': schedule_id,
            'task_name': config.FIBONACCI_TASK,
            'task_data': config.FIBONACCI_DATA,
            'at': at_text,
        }
    )


@dataclass(frozen=True)
class Burst:
    """One burst's lateness samples, in ms, and how long creating its schedules took."""

    started_ms: list[float]
    received_ms: list[float]
    create_sec: float


def burst(ctx: BenchContext, watcher: ResultsWatcher, name: str) -> Burst:
    """BURST_SCHEDULES one-shots due BURST_SPACING_SEC apart; their runs' lateness."""
    sent_at = time.time()
    first_due = sent_at + BURST_LEAD_SEC
    # key: the run's task id, value: its schedule's due time (epoch s, as the node parses it)
    due_by_run: dict[str, float] = {}
    goals = []
    for index in range(BURST_SCHEDULES):
        schedule_id = f'{name}-{index}'
        at_text = datetime.fromtimestamp(first_due + index * BURST_SPACING_SEC, UTC).isoformat()
        due_by_run[run_task_id(schedule_id, 1)] = datetime.fromisoformat(at_text).timestamp()
        goals.append(ctx.client.send_task(SCHEDULE_TASK, schedule_data(schedule_id, at_text)))
    replies = wait_all(goals, config.BURST_TIMEOUT_SEC, f'{name}: {SCHEDULE_TASK} goals')
    created_at = time.time()
    refused = [r for r in replies if task_status(r) != 'DONE']
    if refused:
        raise BenchError(
            f'{name}: {len(refused)} schedules refused, e.g. {error_code(refused[0])!r} '
            f'{refused[0].response.result.task_result if refused[0].response else ""}'
        )
    if created_at >= first_due:
        raise BenchError(
            f'{name}: creating {BURST_SCHEDULES} schedules took {created_at - sent_at:.1f} s, '
            f'past the first due time: raise BURST_LEAD_SEC'
        )
    run_ids = list(due_by_run)
    last_due = max(due_by_run.values())
    statuses = watcher.wait_for(run_ids, last_due - time.time() + RUNS_TIMEOUT_SEC, name)
    failed = {t: s for t, s in statuses.items() if s != 'DONE'}
    if failed:
        raise BenchError(f'{name}: {len(failed)} runs did not end DONE, e.g. {failed}')
    started_ms, received_ms = [], []
    for state in task_states(ctx, run_ids):
        due = due_by_run[state.task_id]
        started_ms.append((seconds(state.started) - due) * 1e3)
        received_ms.append((seconds(state.received) - due) * 1e3)
    return Burst(started_ms, received_ms, created_at - sent_at)


def percentile(samples: list[float], share: float) -> float:
    """Nearest rank (as stats.Summary's p95)."""
    ordered = sorted(samples)
    rank = math.ceil(round(share * len(ordered), 9))  # 0.99 * 300 is 297.00000000000006
    return ordered[max(rank - 1, 0)]


def lateness_text(samples: list[float]) -> str:
    return (
        f'med {statistics.median(samples):.1f} / p99 {percentile(samples, 0.99):.1f} / '
        f'max {max(samples):.1f} ms'
    )


def idle_benchmark(ctx: BenchContext, stored_path: Path) -> tuple[Startup, Startup]:
    """Idle CPU and start-up with an empty store, then with the stored schedules (rows); returns
    both starts (stored, empty). The node is left running on the stored schedules."""
    empty = restart_timed(ctx, 'task_manager_schedules_empty')
    ctx.wait_kept_goals_gone()
    empty_idle = cpu_use(ctx.node.pid, config.IDLE_SEC).percent
    full = restart_timed(ctx, 'task_manager_schedules_10k', history_path=str(stored_path))
    loaded = loaded_schedules(ctx)
    if loaded != STORED_SCHEDULES:
        raise BenchError(f'the node loaded {loaded} schedules, expected {STORED_SCHEDULES}')
    ctx.wait_kept_goals_gone()
    full_idle = cpu_use(ctx.node.pid, config.IDLE_SEC).percent
    ctx.report.add(
        Row(
            benchmark='schedules idle',
            metric=(
                f'node CPU with {STORED_SCHEDULES:,} schedules stored, % of one core over '
                f'{config.IDLE_SEC:.0f} s'
            ),
            measured=f'{full_idle:.2f} %',
            baseline=f'{empty_idle:.2f} % no schedule',
            # no ratio to 0 ticks (see the note on ticks)
            ratio=f'{ratio(full_idle, empty_idle):.2f}x' if empty_idle > 0 else '',
            target=f'< {IDLE_TARGET_PERCENT:.0f} %',
            met=full_idle < IDLE_TARGET_PERCENT,
        ),
        Row(
            benchmark='schedules start-up',
            metric=(
                f'ms from the "task history" log line to "Task Manager ready", '
                f'{STORED_SCHEDULES:,} schedules'
            ),
            measured=f'{full.loading_ms:.0f}',
            baseline=f'{empty.loading_ms:.0f} no schedule',
        ),
    )
    return full, empty


def lateness_benchmark(ctx: BenchContext) -> None:
    watcher = ResultsWatcher(ctx.client)
    try:
        warm_up_results(ctx, watcher)
        bursts = []
        for index in range(BURST_ROUNDS):
            if index > 0:
                ctx.settle()
            print(f'[bench] schedules burst {index + 1} of {BURST_ROUNDS}', flush=True)
            bursts.append(burst(ctx, watcher, f'bench-burst-{index + 1}'))
        if ctx.profiling:  # an extra burst, not measured: sampling pauses the node
            ctx.settle()
            with ctx.profiled(f'schedules: {BURST_SCHEDULES} runs due within one second'):
                burst(ctx, watcher, 'bench-burst-profiled')
    finally:
        watcher.destroy()
    started = [s for b in bursts for s in b.started_ms]
    received = [s for b in bursts for s in b.received_ms]
    median, p99 = statistics.median(started), percentile(started, 0.99)
    what = f'{BURST_SCHEDULES} due within 1 s, x{BURST_ROUNDS} pooled, n={len(started)}'
    ctx.report.add(
        Row(
            benchmark='schedules lateness',
            metric=f'run started - due, ms, median; {what}',
            measured=f'{median:.1f}',
            baseline='',
            target=f'<= {MEDIAN_TARGET_MS:.0f} ms',
            met=median <= MEDIAN_TARGET_MS,
        ),
        Row(
            benchmark='schedules lateness',
            metric=f'run started - due, ms, p99 (max); {what}',
            measured=f'{p99:.1f} ({max(started):.1f})',
            baseline='',
            target=f'<= {P99_TARGET_MS:.0f} ms',
            met=p99 <= P99_TARGET_MS,
        ),
    )
    per_burst = ', '.join(f'{statistics.median(b.started_ms):.1f}' for b in bursts)
    ctx.report.note(
        f'schedules lateness: started - due {lateness_text(started)}; received - due (the '
        f"scheduler's own delay, until the node created the run's request) "
        f'{lateness_text(received)}; medians of started - due per burst: {per_burst} ms; '
        f'creating {BURST_SCHEDULES} schedules through ExecuteTask took '
        + ', '.join(f'{b.create_sec:.2f}' for b in bursts)
        + f' s; {STORED_SCHEDULES:,} other schedules stored'
    )


def run(ctx: BenchContext) -> None:
    stored_path = ctx.log_dir / 'schedules_10k.sqlite'
    fill_sec = fill_schedules(stored_path, STORED_SCHEDULES)
    load_sec = store_load_sec(stored_path)
    try:
        full, empty = idle_benchmark(ctx, stored_path)
        lateness_benchmark(ctx)
    finally:
        ctx.restart_node()
    ctx.report.note(
        f'schedules: filled {STORED_SCHEDULES:,} schedules in {fill_sec:.1f} s (one transaction '
        f'each, through ScheduleStore); ScheduleStore.load of them in the bench: {load_sec:.2f} s; '
        f'from spawn to "Task Manager ready" {full.ready_ms:.0f} ms with them vs '
        f'{empty.ready_ms:.0f} ms with none, to the first ExecuteTask reply '
        f'{full.replied_ms:.0f} vs {empty.replied_ms:.0f} ms (one sample each); idle CPU '
        f'is counted in clock ticks of {1e3 / TICKS_PER_SEC:.0f} ms, so '
        f'{100 / TICKS_PER_SEC / config.IDLE_SEC:.1f} % is one tick over {config.IDLE_SEC:.0f} s'
    )
