"""The deployment users run: the node with its web gateway (a dashboard page open on its event
stream) and its MQTT bridge (connected to a local mosquitto, a cloud client following it)
attached, against the node alone.

The node is restarted for each phase, alone / attached / attached / alone (ABBA), as for a
node setting (node_settings.compare): dispatch latency and burst throughput, each relative to
the direct baseline measured beside it, then 1,000 held tasks until all are IN_PROGRESS
against the same goals sent directly. The dashboard's stream is read by another process
(bench/harness/stream_readers.py), as a browser would; the bridge runs as users start it
(`task-manager-mqtt`), and the cloud's FleetClient follows the robot's results and active lists
(events off; in the bench's process: moving it to a process of its own at
nice 19 changed no row, 2026-11-30).
"""

import contextlib
import statistics
import subprocess
import time
from collections.abc import Iterator

from bench.gateways.mqtt import running_bridge
from bench.gateways.web import HTTP_TIMEOUT_SEC, running_gateway
from bench.harness import config
from bench.harness.client import ActiveTasksWatcher
from bench.harness.context import BenchContext
from bench.harness.processes import cpu_seconds_by_role, nice_by_role
from bench.harness.replies import BenchError
from bench.harness.report import Row
from bench.harness.stats import ratio
from bench.harness.stream_readers import readers_command
from bench.node.concurrency import HoldRun, direct_hold, managed_hold
from bench.node.node_settings import Beside, Setting, Targets, compare

ALONE = Setting('alone', {})
ATTACHED = Setting('gateways attached', {})
TARGETS = Targets(latency=1.10, throughput=0.85)
"""Issue 40: at most 10 % slower at dispatch, at most 15 % fewer tasks/s on the burst."""
DASHBOARD_STREAMS = 1
CPU_SAMPLE_TASKS = 200
NODE_ROLE = 'node'
GATEWAY_ROLES = ('web gateway', 'MQTT bridge')


@contextlib.contextmanager
def _dashboard(ctx: BenchContext) -> Iterator[None]:
    """The web gateway, with one page open on its event stream (read by another process)."""
    with running_gateway(ctx) as (gateway, _http):
        readers = subprocess.Popen(
            readers_command(gateway.url, gateway.token, DASHBOARD_STREAMS),
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert readers.stdin is not None and readers.stdout is not None
        try:
            if readers.stdout.readline().strip() != 'open':
                raise BenchError('the dashboard event stream did not open')
            yield
        finally:
            readers.stdin.close()
            readers.wait(HTTP_TIMEOUT_SEC)


def _beside(ctx: BenchContext) -> Beside:
    """What runs beside the node in each phase: the gateways when attached, else nothing."""

    def beside(setting: Setting) -> contextlib.AbstractContextManager[object]:
        if setting is not ATTACHED:
            return contextlib.nullcontext()
        stack = contextlib.ExitStack()
        with stack:
            stack.enter_context(_dashboard(ctx))
            stack.enter_context(running_bridge(ctx))
            return stack.pop_all()

    return beside


class CpuPerTask:
    """Per setting, each process's CPU ms per instant task, over CPU_SAMPLE_TASKS in a row."""

    def __init__(self, ctx: BenchContext) -> None:
        self._ctx = ctx
        # key: setting's name, value: per role, ms of CPU per task in each phase
        self.ms: dict[str, dict[str, list[float]]] = {ALONE.name: {}, ATTACHED.name: {}}
        self.nice: dict[str, int] = {}
        """Each gateway's nice value, as it ran (issue 40: their default is 10)."""

    def measure(self, setting: Setting) -> None:
        before = cpu_seconds_by_role()
        for _ in range(CPU_SAMPLE_TASKS):
            self._ctx.fibonacci_task_ms()
        after = cpu_seconds_by_role()
        self.nice.update((r, n) for r, n in nice_by_role().items() if r in GATEWAY_ROLES)
        for role, seconds in after.items():
            per_task_ms = (seconds - before.get(role, 0.0)) * 1000 / CPU_SAMPLE_TASKS
            self.ms[setting.name].setdefault(role, []).append(per_task_ms)

    def note(self) -> str:
        def line(setting: Setting) -> str:
            by_role = sorted(
                ((statistics.median(ms), role) for role, ms in self.ms[setting.name].items()),
                reverse=True,
            )
            total = sum(ms for ms, _ in by_role)
            parts = ', '.join(f'{role} {ms:.1f}' for ms, role in by_role if ms >= 0.05)
            return f'{setting.name} {total:.1f} ({parts})'

        return (
            f'CPU ms per instant action task by process, {CPU_SAMPLE_TASKS} tasks one by one, '
            f'median of the phases: {line(ALONE)}; {line(ATTACHED)}; {self._over_the_node()}'
        )

    def _over_the_node(self) -> str:
        """Each gateway's CPU over the node's in the same phase: the machine's speed drifts by
        as much as a half within an hour here, and moves both alike (2026-11-29)."""
        attached = self.ms[ATTACHED.name]
        node = attached.get(NODE_ROLE, [])
        parts = []
        for role in GATEWAY_ROLES:
            ratios = [
                ms / node_ms
                for ms, node_ms in zip(attached.get(role, []), node, strict=False)
                if node_ms
            ]
            if ratios:
                parts.append(f'{role} {statistics.median(ratios):.2f}')
        nice = ', '.join(f'{role} {value}' for role, value in sorted(self.nice.items()))
        return f'over the node, attached: {", ".join(parts)}; nice: {nice}' if parts else ''


class HeldRamps:
    """Per setting, each phase's ramp to all IN_PROGRESS over the direct ramp beside it."""

    def __init__(self, ctx: BenchContext) -> None:
        self._ctx = ctx
        self.shares: dict[str, list[float]] = {ALONE.name: [], ATTACHED.name: []}
        self.ramps_ms: dict[str, list[float]] = {ALONE.name: [], ATTACHED.name: []}
        self.failures: list[str] = []
        # when the last held goals ended: at first, when the benchmark began (those of the
        # benchmarks before it were gone by then)
        self._held_ended = time.monotonic()

    def measure(self, setting: Setting, _index: int) -> None:
        count = config.CONCURRENT_TASKS
        # rclpy's hold server walks the goals it keeps: the last ramp's must be gone (a phase's
        # dispatch samples and bursts usually take longer than they are kept)
        self._ctx.wait_kept_goals_gone(since=self._held_ended)
        direct = direct_hold(self._ctx, count)
        watcher = ActiveTasksWatcher(self._ctx.client.harness)
        try:
            watcher.wait_until(bool, config.CONNECT_TIMEOUT_SEC, 'the current list')
            managed: HoldRun = managed_hold(self._ctx, watcher, count)[0]
        except BenchError as error:  # the phase's dispatch and bursts still count
            self.failures.append(f'{setting.name}: {error}')
            return
        finally:
            watcher.destroy()
            self._held_ended = time.monotonic()
        self.shares[setting.name].append(ratio(managed.ramp_sec, direct.ramp_sec))
        self.ramps_ms[setting.name].append(managed.ramp_sec * 1000)

    def row(self) -> Row:
        if self.failures:
            return Row(
                f'{ATTACHED.name} vs {ALONE.name}: {config.CONCURRENT_TASKS} held',
                'FAILED',
                '; '.join(self.failures),
                '',
            )
        attached = statistics.median(self.shares[ATTACHED.name])
        alone = statistics.median(self.shares[ALONE.name])
        return Row(
            benchmark=f'{ATTACHED.name} vs {ALONE.name}: {config.CONCURRENT_TASKS} held',
            metric='ms until all IN_PROGRESS, med of 2 (each over direct beside it)',
            measured=f'{statistics.median(self.ramps_ms[ATTACHED.name]):.0f}',
            baseline=f'{statistics.median(self.ramps_ms[ALONE.name]):.0f} {ALONE.name}',
            ratio=f'{ratio(attached, alone):.2f}x',
            target='',
            met=None,
        )


def run(ctx: BenchContext) -> None:
    held = HeldRamps(ctx)
    cpu = CpuPerTask(ctx)

    def in_phase(setting: Setting, index: int) -> None:
        cpu.measure(setting)
        held.measure(setting, index)

    started = time.perf_counter()
    compare(ctx, ALONE, ATTACHED, beside=_beside(ctx), in_phase=in_phase, targets=TARGETS)
    ctx.report.add(held.row())
    ctx.report.note(cpu.note())
    ctx.report.note(
        f'attached: the web gateway with {DASHBOARD_STREAMS} event stream open and the MQTT '
        f'bridge on a local mosquitto, a FleetClient following; 4 phases in '
        f'{time.perf_counter() - started:.0f} s'
    )
