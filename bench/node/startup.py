"""Start-up and idle cost of the node: how long from `task-manager` being started until it
answers an ExecuteTask goal, and how much CPU it uses when nothing happens.

Start-up: the node is stopped and started again, STARTUP_SAMPLES times; each sample runs
from just before the process is spawned until the first ExecuteTask round trip (a goal for
an unknown task, answered at once) has its reply: the interpreter and rclpy loading, the
parameters, DDS discovery of the node by the bench's client, and the round trip. Idle CPU:
the node's user + system CPU time (psutil) over IDLE_SEC with no task, after the pause that
lets its ExecuteTask server drop the goals it keeps, beside its threads' wake-ups and what this
machine bills one (wake_ups.py).
"""

import re
import time

from bench.harness import config
from bench.harness.context import BenchContext
from bench.harness.processes import start_node
from bench.harness.replies import BenchError
from bench.harness.report import Row
from bench.harness.stats import Summary
from bench.harness.wake_ups import cpu_use, wake_up_context

STARTUP_TARGET_MS = 1500.0
IDLE_CPU_TARGET_PERCENT = 0.5
# the ROS log line's stamp (wall clock, s) of the node's ready line
READY_LINE = re.compile(r'\[(?P<stamp>\d+\.\d+)\] \[task_manager\]: Task Manager ready')


def startup_ms(ctx: BenchContext) -> tuple[float, float]:
    """(ms until the first ExecuteTask reply, ms until the node logged that it is ready)."""
    ctx.node.stop()
    params_file = config.write_node_params(ctx.log_dir, 'startup_params')
    spawned_at = time.time()
    started = time.perf_counter()
    ctx.node = start_node(params_file, ctx.log_dir, 'startup')
    ctx.connect()
    replied_ms = (time.perf_counter() - started) * 1000
    ready = READY_LINE.search(ctx.node.log_path.read_text(errors='replace'))
    if ready is None:
        raise BenchError('the node did not log "Task Manager ready"')
    return replied_ms, (float(ready['stamp']) - spawned_at) * 1000


def run(ctx: BenchContext) -> None:
    pairs = [startup_ms(ctx) for _ in range(config.STARTUP_SAMPLES)]
    samples = [replied for replied, _ in pairs]
    startup = Summary.of(samples)
    ready = Summary.of([ready for _, ready in pairs])
    ctx.wait_kept_goals_gone()
    idle = cpu_use(ctx.node.pid, config.IDLE_SEC)
    ctx.report.add(
        Row(
            benchmark='startup',
            metric=f'ms from spawn to the first ExecuteTask reply, med / p95, n={startup.count}',
            measured=startup.text(0),
            baseline='',
            target=f'<= {STARTUP_TARGET_MS:.0f} ms',
            met=startup.median <= STARTUP_TARGET_MS,
        ),
        Row(
            benchmark='idle',
            metric=f'node CPU with no task, % of one core over {config.IDLE_SEC:.0f} s',
            measured=f'{idle.percent:.2f} %',
            baseline=wake_up_context(idle),
            target=f'< {IDLE_CPU_TARGET_PERCENT} %',
            met=idle.percent < IDLE_CPU_TARGET_PERCENT,
        ),
    )
    ctx.report.note(
        f'startup: samples {", ".join(f"{s:.0f}" for s in samples)} ms; the node logged '
        f'"Task Manager ready" after {ready.text(0)} ms (med / p95), the rest is discovery'
    )
