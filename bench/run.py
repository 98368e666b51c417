"""Runs every benchmark against one node and prints the machine and the table of results."""

import argparse
import contextlib
import json
import os
import tempfile
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import asdict
from pathlib import Path

import rclpy

from bench.fleet import console
from bench.gateways import attached, mqtt, vda5050, web
from bench.harness import config
from bench.harness.client import BenchClient
from bench.harness.context import BenchContext
from bench.harness.processes import OtherLoad, start_node, start_servers
from bench.harness.profiler import Profile, py_spy_executable
from bench.harness.report import Row, machine_lines, table
from bench.node import (
    admission,
    concurrency,
    dispatch,
    events,
    feedback,
    history,
    isolation,
    leak,
    memory,
    mission,
    schedules,
    startup,
    throughput,
)

TOP_FUNCTIONS = 15

# name: benchmark, in the order they run (the heaviest last)
BENCHMARKS: dict[str, Callable[[BenchContext], None]] = {
    'dispatch': dispatch.run,
    'throughput': throughput.run,
    'mission': mission.run,
    'isolation': isolation.run,
    'feedback': feedback.run,
    'concurrency': concurrency.run,
    'web': web.run,
    'mqtt': mqtt.run,
    'vda5050': vda5050.run,
    'console': console.run,
    # last: they restart the node for each phase, then once more with the default parameters
    'admission': admission.run,
    'attached': attached.run,
    'events': events.run,
    'history': history.run,
    'schedules': schedules.run,
    'leak': leak.run,
    'memory': memory.run,
    'startup': startup.run,
}

# benchmarks that send no goal to the node or its servers (the fleet console's robots are
# simulated without ROS): they need not wait for the goals kept before them, nor make the next
# one wait
WITHOUT_GOALS = {'console'}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog='python -m bench', description=__doc__)
    parser.add_argument(
        '--only', nargs='+', choices=list(BENCHMARKS), help='run only these benchmarks'
    )
    parser.add_argument('--no-profile', action='store_true', help='skip the py-spy profile')
    parser.add_argument('--json', type=Path, help='also write the results to this file')
    return parser.parse_args(argv)


@contextlib.contextmanager
def running_bench(log_dir: Path, profiling: bool) -> Iterator[BenchContext]:
    """The servers, the node and the bench client, all stopped in reverse order afterwards."""
    with contextlib.ExitStack() as stack:
        rclpy.init()
        stack.callback(rclpy.try_shutdown)
        servers = start_servers(log_dir)
        stack.callback(servers.stop)
        node = start_node(config.write_node_params(log_dir), log_dir)
        stack.callback(node.stop)  # stopping twice is harmless
        client = BenchClient()
        stack.callback(client.close)
        ctx = BenchContext(client, node, servers, log_dir, profiling)
        stack.callback(lambda: ctx.node.stop())  # the node running then (see restart_node)
        ctx.connect()
        yield ctx


def run_benchmark(ctx: BenchContext, name: str) -> bool:
    started = time.perf_counter()
    other_load = OtherLoad()
    print(f'[bench] {name} ...', flush=True)
    try:
        BENCHMARKS[name](ctx)
    except Exception as error:  # one broken benchmark must not hide the others' figures
        traceback.print_exc()
        ctx.report.add(Row(name, 'FAILED', str(error).splitlines()[0], ''))
        return False
    finally:
        ctx.report.other_load[name] = other_load.cores()
    print(f'[bench] {name} done in {time.perf_counter() - started:.1f} s', flush=True)
    return True


def profile_lines(title: str, profile: Profile) -> list[str]:
    def rows(counts: Counter[str], limit: int = TOP_FUNCTIONS) -> list[str]:
        return [f'  {profile.share(n):6.1%}  {name}' for name, n in counts.most_common(limit)]

    return [
        f'profile of the node, {title} (py-spy record --function --gil, {profile.samples} samples)',
        '  where the time goes:',
        *rows(profile.areas(), limit=len(profile.areas())),
        '  top functions by own time (self):',
        *rows(profile.self_samples()),
        "  the node's own functions, including callees:",
        *rows(profile.node_inclusive_samples()),
        '',
    ]


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    names = args.only or list(BENCHMARKS)
    started = time.perf_counter()
    machine = machine_lines()
    log_dir = Path(tempfile.mkdtemp(prefix='task_manager_bench_'))
    # the ROS log files of the bench's processes go there too, not to ~/.ros
    os.environ['ROS_HOME'] = str(log_dir / 'ros_home')
    profiling = not args.no_profile and bool(py_spy_executable())
    if not args.no_profile and not profiling:
        print('[bench] py-spy not found: no profile (make install installs it)')
    with running_bench(log_dir, profiling) as ctx:
        ok = True
        goals_ended = time.monotonic()
        for index, name in enumerate(names):
            # each starts once the goals of those before it are gone
            if index > 0 and name not in WITHOUT_GOALS:
                ctx.wait_kept_goals_gone(since=goals_ended)
            ok = run_benchmark(ctx, name) and ok
            if name not in WITHOUT_GOALS:
                goals_ended = time.monotonic()
    lines = [
        *machine,
        '',
        table(ctx.report.rows),
        *(f'note: {n}' for n in ctx.report.notes),
        f'CPU used by other processes while each benchmark ran, in cores of {os.cpu_count()}: '
        + ', '.join(f'{name} {cores:.2f}' for name, cores in ctx.report.other_load.items()),
        '',
        *(line for title, p in ctx.profiles.items() for line in profile_lines(title, p)),
        f'logs and profile: {log_dir}',
        f'wall time of the bench: {time.perf_counter() - started:.0f} s',
    ]
    print('\n'.join(lines), flush=True)
    if args.json:
        results = {'machine': machine, 'rows': [asdict(r) for r in ctx.report.rows]}
        args.json.write_text(json.dumps(results, indent=2))
    return 0 if ok else 1
