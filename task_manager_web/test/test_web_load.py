"""The gateway under load, against a real gateway process and a real Task Manager node."""

import statistics
import time

import httpx
import psutil
import pytest

from task_manager.testing.gateway import Robot
from task_manager_web.testing import GatewayProcess

pytestmark = pytest.mark.ros

WARM_UP_READS = 100
READS = 1000
MEMORY_GROWTH_MAX_BYTES = 4 * 2**20
"""Of each process over READS reads: 0.2 MB measured (a parameter client per read grew the
gateway by 0.6 MB a read and the node by 0.13 MB)."""
COMPARED_READS = 100
"""The first and the last this many reads are compared (their medians)."""


def test_reading_the_declared_tasks_1000_times_grows_no_process_and_slows_nothing(
    robot: Robot, gateway: GatewayProcess, http: httpx.Client
) -> None:
    processes = {
        'node': psutil.Process(robot.process.process.pid),
        'gateway': psutil.Process(gateway.process.pid),
    }

    def read() -> float:
        began = time.perf_counter()
        response = http.get('/api/tasks')
        assert response.status_code == 200, response.text
        return time.perf_counter() - began

    for _ in range(WARM_UP_READS):
        read()
    before = {name: process.memory_info().rss for name, process in processes.items()}
    times = [read() for _ in range(READS)]
    after = {name: process.memory_info().rss for name, process in processes.items()}

    first = statistics.median(times[:COMPARED_READS])
    last = statistics.median(times[-COMPARED_READS:])
    growth = {name: after[name] - before[name] for name in processes}
    print(
        f'\n{READS} reads of /api/tasks: median of the first {COMPARED_READS} '
        f'{first * 1000:.1f} ms, of the last {last * 1000:.1f} ms; RSS growth '
        + ', '.join(f'{name} {growth[name] / 2**20:+.1f} MB' for name in processes)
    )
    assert all(bytes_ <= MEMORY_GROWTH_MAX_BYTES for bytes_ in growth.values()), growth
    assert last <= 1.5 * first + 0.002
