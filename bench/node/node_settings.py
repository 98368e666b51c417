"""The cost of a node setting: dispatch latency and burst throughput with it vs without.

A node parameter read at start (publish_task_events, history_path) needs a restart to
change, so the node is restarted for each phase, in the order without, with, with, without
(SETTING_PHASES), drift in the machine's load hitting both alike. Each phase repeats the
dispatch benchmark (fewer samples per phase, as many per setting) and the throughput
benchmark's bursts, each against the direct baseline measured beside it.

The ratios compare the manager's cost relative to its direct baseline: for latency,
(median with / its direct median) / (median without / its direct median); for throughput,
the median over bursts of (tasks/s / the direct goals/s of the burst beside it), with vs
without. The machine's drift between phases (other processes, the DDS discovery traffic of
a restart) then cancels out; the raw figures stay in the table and the direct ones in a note.
Finally the node is restarted once more with the default parameters.
"""

import contextlib
import statistics
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from typing import Any

from bench.harness import config
from bench.harness.context import BenchContext
from bench.harness.report import Row
from bench.harness.stats import Summary, ratio
from bench.node import throughput
from bench.node.dispatch import interleaved

LATENCY_TARGET = 1.10
THROUGHPUT_TARGET = 0.90


@dataclass(frozen=True)
class Setting:
    """A node configuration of the comparison: its name in the report and its parameters."""

    name: str
    parameters: dict[str, Any]


@dataclass
class Figures:
    """Everything measured in one setting, over all its phases."""

    action_ms: list[float] = field(default_factory=list)
    action_direct_ms: list[float] = field(default_factory=list)
    service_ms: list[float] = field(default_factory=list)
    service_direct_ms: list[float] = field(default_factory=list)
    burst_rates: list[float] = field(default_factory=list)
    direct_rates: list[float] = field(default_factory=list)
    tasks: int = 0
    """Tasks measured (warm-up excluded)."""

    def burst_shares(self) -> list[float]:
        """Each burst's tasks/s over the direct goals/s of the burst beside it."""
        return [ratio(m, d) for m, d in zip(self.burst_rates, self.direct_rates, strict=True)]


# called after each phase's measurements: (the setting, tasks measured in the phase)
PhaseCheck = Callable[[Setting, int], None]
# what runs beside the node during a phase of a setting (the gateways attached, say)
Beside = Callable[[Setting], AbstractContextManager[object]]
# measured last in each phase, beside the node as the phase has it: (the setting, phase index)
InPhase = Callable[[Setting, int], None]


@dataclass(frozen=True)
class Targets:
    """With vs without: the latency ratio at most, the throughput share at least."""

    latency: float = LATENCY_TARGET
    throughput: float = THROUGHPUT_TARGET


def _nothing_beside(_setting: Setting) -> AbstractContextManager[object]:
    return contextlib.nullcontext()


def _bursts(ctx: BenchContext, figures: Figures, phase_index: int) -> None:
    count = config.THROUGHPUT_TASKS
    for burst_index in range(config.SETTING_BURSTS):
        ctx.settle()
        round_index = phase_index * config.SETTING_BURSTS + burst_index
        if round_index % 2 == 0:  # which goes first alternates, as in the throughput benchmark
            figures.burst_rates.append(throughput.manager_burst(ctx, count, round_index))
            figures.direct_rates.append(throughput.direct_burst(ctx, count, round_index))
        else:
            figures.direct_rates.append(throughput.direct_burst(ctx, count, round_index))
            figures.burst_rates.append(throughput.manager_burst(ctx, count, round_index))
        figures.tasks += count


def _phase(
    ctx: BenchContext,
    setting: Setting,
    index: int,
    figures: Figures,
    on_warmed_up: Callable[[], object],
) -> int:
    """Measure in `setting` (its node restarted); return how many tasks were measured."""
    samples = config.SETTING_DISPATCH_SAMPLES
    tasks_before = figures.tasks
    interleaved(ctx.fibonacci_task_ms, ctx.fibonacci_direct_ms, config.WARM_UP_SAMPLES)
    interleaved(ctx.trigger_task_ms, ctx.trigger_direct_ms, config.WARM_UP_SAMPLES)
    ctx.settle()
    on_warmed_up()
    action, action_direct = interleaved(ctx.fibonacci_task_ms, ctx.fibonacci_direct_ms, samples)
    ctx.settle()
    service, service_direct = interleaved(ctx.trigger_task_ms, ctx.trigger_direct_ms, samples)
    figures.action_ms += action
    figures.action_direct_ms += action_direct
    figures.service_ms += service
    figures.service_direct_ms += service_direct
    figures.tasks += 2 * samples
    _bursts(ctx, figures, index)
    return figures.tasks - tasks_before


def compare(
    ctx: BenchContext,
    without: Setting,
    with_: Setting,
    after_phase: PhaseCheck | None = None,
    on_warmed_up: Callable[[], object] = lambda: None,
    beside: Beside = _nothing_beside,
    in_phase: InPhase | None = None,
    targets: Targets = Targets(),
) -> tuple[Figures, Figures]:
    """Measure both settings (ABBA), add the three rows; return (without, with) figures."""
    # key: setting's name, value: the figures of its phases
    figures = {without.name: Figures(), with_.name: Figures()}
    try:
        for index, measured in enumerate(config.SETTING_PHASES):
            setting = with_ if measured else without
            print(f'[bench] phase {index + 1}: {setting.name}', flush=True)
            log_name = f'task_manager_{index + 1}_{setting.name.replace(" ", "_")}'
            ctx.restart_node(log_name, **setting.parameters)
            with beside(setting):
                tasks = _phase(ctx, setting, index, figures[setting.name], on_warmed_up)
                if in_phase is not None:
                    in_phase(setting, index)
            if after_phase is not None:
                after_phase(setting, tasks)
    finally:
        ctx.restart_node()  # a new node keeps no goals: no pause needed
    base, measured_figures = figures[without.name], figures[with_.name]
    ctx.report.add(
        _latency_row('action', with_, without, measured_figures.action_ms,
                     measured_figures.action_direct_ms, base.action_ms, base.action_direct_ms,
                     targets.latency),
        _latency_row('service', with_, without, measured_figures.service_ms,
                     measured_figures.service_direct_ms, base.service_ms, base.service_direct_ms,
                     targets.latency),
        _throughput_row(with_, without, measured_figures, base, targets.throughput),
    )  # fmt: skip
    ctx.report.note(_direct_note(with_, without, measured_figures, base))
    return base, measured_figures


def _latency_row(
    kind: str,
    with_: Setting,
    without: Setting,
    measured_ms: list[float],
    measured_direct_ms: list[float],
    base_ms: list[float],
    base_direct_ms: list[float],
    target: float,
) -> Row:
    measured, base = Summary.of(measured_ms), Summary.of(base_ms)
    factor = ratio(
        ratio(measured.median, statistics.median(measured_direct_ms)),
        ratio(base.median, statistics.median(base_direct_ms)),
    )
    return Row(
        benchmark=f'{with_.name} vs {without.name}: dispatch {kind}',
        metric=f'round trip ms, med / p95, n={measured.count}',
        measured=measured.text(),
        baseline=f'{base.text()} {without.name}',
        ratio=f'{factor:.2f}x',
        target=f'<= {target:.2f}x',
        met=factor <= target,
    )


def _spread(rates: list[float]) -> str:
    return f'{statistics.median(rates):.0f} ({min(rates):.0f}-{max(rates):.0f})'


def _throughput_row(
    with_: Setting, without: Setting, measured: Figures, base: Figures, target: float
) -> Row:
    share = ratio(
        statistics.median(measured.burst_shares()), statistics.median(base.burst_shares())
    )
    return Row(
        benchmark=f'{with_.name} vs {without.name}: throughput',
        metric=(
            f'tasks/s, {config.THROUGHPUT_TASKS} at once, med (min-max) of '
            f'{len(measured.burst_rates)}'
        ),
        measured=_spread(measured.burst_rates),
        baseline=f'{_spread(base.burst_rates)} {without.name}',
        ratio=f'{share:.0%}',
        target=f'>= {target:.0%}',
        met=share >= target,
    )


def _direct_note(with_: Setting, without: Setting, measured: Figures, base: Figures) -> str:
    """The direct baselines in both settings: the drift the ratios take out."""

    def med(samples: list[float]) -> float:
        return statistics.median(samples)

    return (
        f'{with_.name} vs {without.name}: ratios are relative to the direct baseline beside '
        f'each sample; direct medians ({with_.name} vs {without.name} phases): action '
        f'{med(measured.action_direct_ms):.2f} vs {med(base.action_direct_ms):.2f} ms, service '
        f'{med(measured.service_direct_ms):.2f} vs {med(base.service_direct_ms):.2f} ms, burst '
        f'{med(measured.direct_rates):.0f} vs {med(base.direct_rates):.0f} goals/s'
    )
