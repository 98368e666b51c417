"""The machine the bench ran on, and the table of results."""

import importlib.metadata
import importlib.util
import os
import platform
import re
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

from rclpy.utilities import get_rmw_implementation_identifier

NODE_ENTRY_POINT = 'task_manager.ros.node_process'
BENCH_EXECUTOR = 'SingleThreadedExecutor (spun in a background thread)'
SERVERS_EXECUTOR = 'SingleThreadedExecutor (separate process)'


@dataclass(frozen=True)
class Row:
    """One line of the results table; `met` is None where there is no target."""

    benchmark: str
    metric: str
    measured: str
    baseline: str
    ratio: str = ''
    target: str = ''
    met: bool | None = None


@dataclass
class Report:
    rows: list[Row] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    # key: benchmark, value: cores used by other processes while it ran
    other_load: dict[str, float] = field(default_factory=dict)

    def add(self, *rows: Row) -> None:
        self.rows.extend(rows)

    def note(self, text: str) -> None:
        self.notes.append(text)


def cpu_model() -> str:
    cpuinfo = Path('/proc/cpuinfo')
    text = cpuinfo.read_text() if cpuinfo.exists() else ''
    found = re.search(r'^model name\s*:\s*(.+)$', text, re.MULTILINE)
    return found.group(1).strip() if found else platform.processor() or 'unknown CPU'


def node_executor() -> str:
    """The executor class the node's entry point spins, read from its source.

    Read, not imported: the node's modules are meant to be imported by its entry point.
    """
    spec = importlib.util.find_spec(NODE_ENTRY_POINT)
    source = Path(spec.origin).read_text() if spec and spec.origin else ''
    names = sorted(set(re.findall(r'(\w*Executor)\(', source)))
    return ', '.join(names) or 'unknown'


def code_version() -> str:
    """The commit measured, and whether the node's code had uncommitted changes."""
    root = Path(__file__).resolve().parents[2]
    try:
        commit = subprocess.run(
            ['git', 'rev-parse', '--short', 'HEAD'], cwd=root, capture_output=True, text=True
        ).stdout.strip()
        changes = subprocess.run(
            ['git', 'status', '--porcelain', '--', 'task_manager'],
            cwd=root,
            capture_output=True,
            text=True,
        ).stdout.strip()
    except OSError:
        return 'unknown (no git)'
    return f'{commit or "unknown"}' + (' + uncommitted changes in task_manager/' if changes else '')


def machine_lines() -> list[str]:
    load_1, load_5, _ = os.getloadavg()
    return [
        f'code    : {code_version()}',
        f'machine : {os.cpu_count()} cores, {cpu_model()}, '
        f'{platform.system()} {platform.release()}',
        f'python  : {platform.python_version()}; rclpy '
        f'{importlib.metadata.version("rclpy")}; RMW {get_rmw_implementation_identifier()}; '
        f'ROS_DOMAIN_ID {os.environ.get("ROS_DOMAIN_ID")}',
        f'executor: node {node_executor()} (task_manager.ros.node_process); bench client '
        f'{BENCH_EXECUTOR}; servers {SERVERS_EXECUTOR}',
        f'load    : {load_1:.2f} (1 min), {load_5:.2f} (5 min) at start',
    ]


def _met_text(met: bool | None) -> str:
    return '' if met is None else ('yes' if met else 'NO')


def table(rows: list[Row]) -> str:
    header = ('benchmark', 'metric', 'manager', 'baseline', 'ratio', 'target', 'met')
    cells = [header] + [
        (r.benchmark, r.metric, r.measured, r.baseline, r.ratio, r.target, _met_text(r.met))
        for r in rows
    ]
    widths = [max(len(row[i]) for row in cells) for i in range(len(header))]
    lines = [' | '.join(c.ljust(w) for c, w in zip(row, widths, strict=True)) for row in cells]
    lines.insert(1, '-+-'.join('-' * w for w in widths))
    return '\n'.join(line.rstrip() for line in lines)
