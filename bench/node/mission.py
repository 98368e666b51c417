"""A mission of many instant subtasks: total time, and the cost of each subtask."""

import json
import statistics

from bench.harness import config
from bench.harness.context import BenchContext
from bench.harness.report import Row
from bench.harness.stats import ratio

MISSION_TIMEOUT_SEC = 60.0


def mission_data(subtasks: int) -> str:
    subtask = {
        'task_name': config.FIBONACCI_TASK,
        'task_data': config.FIBONACCI_DATA,
        'allow_skipping': False,
    }
    return json.dumps({'subtasks': [subtask] * subtasks})


def run(ctx: BenchContext) -> None:
    data = mission_data(config.MISSION_SUBTASKS)
    # the baseline, measured just before under the same conditions
    single_ms = statistics.median(ctx.fibonacci_task_ms() for _ in range(config.WARM_UP_SAMPLES))
    totals_ms = [
        ctx.task_latency_ms(config.MISSION_TASK, data, MISSION_TIMEOUT_SEC)
        for _ in range(config.MISSION_ROUNDS)
    ]
    total_ms = statistics.median(totals_ms)
    per_subtask_ms = total_ms / config.MISSION_SUBTASKS
    ctx.report.add(
        Row(
            benchmark='mission',
            metric=f'{config.MISSION_SUBTASKS} instant subtasks: total ms, med of {len(totals_ms)}',
            measured=f'{total_ms:.0f} ({min(totals_ms):.0f}-{max(totals_ms):.0f})',
            baseline='',
        ),
        Row(
            benchmark='mission',
            metric='ms per subtask vs one task dispatched alone',
            measured=f'{per_subtask_ms:.2f}',
            baseline=f'{single_ms:.2f} single task',
            ratio=f'{ratio(per_subtask_ms, single_ms):.2f}x',
        ),
    )
