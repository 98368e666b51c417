"""The gateway under load, against a real gateway process and a real Task Manager node."""

import json
import socket
import statistics
import time
from collections import Counter
from collections.abc import Callable

import httpx
import psutil
import pytest

from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check
from task_manager_web.doors.settings import MAX_READS_PER_CLIENT
from task_manager_web.testing import GatewayProcess

pytestmark = pytest.mark.ros

WARM_UP_READS = 100
READS = 1000
MEMORY_GROWTH_MAX_BYTES = 4 * 2**20
"""Of each process over READS reads: 0.2 MB measured (a parameter client per read grew the
gateway by 0.6 MB a read and the node by 0.13 MB)."""
WINDOW_READS = 100
"""The reads are timed in windows of this many: the CPU the gateway and the node spent on each
(wall times, printed too, follow what else the machine does: with four test processes beside,
the last 100 took 41 ms each against 18 ms for the first, and no more CPU)."""
COMPARED_WINDOWS = 3
"""The quickest of the first and of the last this many windows are compared: what else the
machine does makes a window dearer, never cheaper (at four test processes one window of 100
took 700 ms of CPU against 410 ms for the first, the code the same), while a read that leaves
work behind makes every later window dearer."""
CPU_TICK_SEC = 0.01
"""The kernel counts a process's CPU time in ticks of 10 ms."""


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

    def cpu_sec() -> float:
        return sum(sum(process.cpu_times()[:2]) for process in processes.values())

    def timed_reads(count: int) -> tuple[list[float], float]:
        """Wall time of each read, and the CPU the two processes spent on them all."""
        cpu_before = cpu_sec()
        times = [read() for _ in range(count)]
        return times, cpu_sec() - cpu_before

    for _ in range(WARM_UP_READS):
        read()
    before = {name: process.memory_info().rss for name, process in processes.items()}
    windows = [timed_reads(WINDOW_READS) for _ in range(READS // WINDOW_READS)]
    after = {name: process.memory_info().rss for name, process in processes.items()}

    growth = {name: after[name] - before[name] for name in processes}
    first_cpu = min(cpu for _, cpu in windows[:COMPARED_WINDOWS])
    last_cpu = min(cpu for _, cpu in windows[-COMPARED_WINDOWS:])
    print(
        f'\n{READS} reads of /api/tasks, CPU of each {WINDOW_READS}: '
        + ', '.join(f'{cpu * 1000:.0f}' for _, cpu in windows)
        + ' ms (median read of the first and last window '
        f'{statistics.median(windows[0][0]) * 1000:.1f} and '
        f'{statistics.median(windows[-1][0]) * 1000:.1f} ms); RSS growth '
        + ', '.join(f'{name} {growth[name] / 2**20:+.1f} MB' for name in processes)
    )
    assert all(bytes_ <= MEMORY_GROWTH_MAX_BYTES for bytes_ in growth.values()), growth
    assert last_cpu <= 1.5 * first_cpu + 5 * CPU_TICK_SEC


FLOOD_READS = 500
CONTROL_ANSWER_MAX_SEC = 2.0
"""0.08 to 0.19 s measured on 2026-11-25, 0.14 to 0.30 s with two processes spinning beside (was
0.2 to 0.65 s with all reads in one small pool of threads, 2.2 to 6.9 s in the issue). On
2026-11-26 0.21 to 0.44 s alone and 0.41 to 0.55 s in a full run; not the code: in one sitting
that day, the code of 2026-11-25 (5c373a6) and of before issue 37 (b26d7f4), run from worktrees,
answered in 0.26 to 0.69 s too. On 2026-11-27, in full runs in a slow hour of the machine (the
same tests took 13 % more CPU), 0.74 and 1.27 s (1.24 s at four test processes). The gateway
itself must take in the 500 connections meanwhile, which takes what the machine gives: the
bound is 2 s, under the 2.2 s the bug took at least."""


def flood(gateway: GatewayProcess, path: str, count: int) -> list[socket.socket]:
    """`count` GET requests of `path`, each on a connection of its own, sent and not read."""
    url = httpx.URL(gateway.url)
    request = (
        f'GET {path} HTTP/1.1\r\nHost: {url.host}:{url.port}\r\n'
        f'Authorization: Bearer {gateway.token}\r\nConnection: close\r\n\r\n'
    ).encode()
    connections = []
    for _ in range(count):
        connection = socket.create_connection((url.host, url.port), timeout=TIMEOUT_SEC)
        connection.sendall(request)
        connections.append(connection)
    return connections


def replies(connections: list[socket.socket]) -> list[tuple[int, bytes]]:
    """The status and body of each connection's reply (read to its end)."""
    answered = []
    for connection in connections:
        with connection:
            reply = b''
            while chunk := connection.recv(65536):
                reply += chunk
        head, _, body = reply.partition(b'\r\n\r\n')
        answered.append((int(head.split(b' ', 2)[1]), body))
    return answered


def timed(send: Callable[[], httpx.Response]) -> tuple[httpx.Response, float]:
    began = time.perf_counter()
    response = send()
    return response, time.perf_counter() - began


def test_stop_and_cancel_are_answered_at_once_under_500_reads(
    robot: Robot, gateway: GatewayProcess, http: httpx.Client
) -> None:
    for task_id in ('to-cancel', 'to-stop'):
        body = {'task_name': 'fib', 'task_data': {'order': 1}, 'task_id': task_id}
        assert http.post('/api/tasks/start', json=body).status_code == 202
    robot.fib.wait_for_goals(2, TIMEOUT_SEC)
    _, idle_sec = timed(lambda: http.get('/api/tasks/to-cancel'))

    reads = flood(gateway, '/api/active', FLOOD_READS)
    cancel, cancel_sec = timed(
        lambda: http.post('/api/tasks/cancel', json={'task_ids': ['to-cancel']})
    )
    cancel_reads = replies(reads)
    reads = flood(gateway, '/api/active', FLOOD_READS)
    stop, stop_sec = timed(lambda: http.post('/api/stop'))
    stop_reads = replies(reads)

    counts = [Counter(status for status, _ in each) for each in (cancel_reads, stop_reads)]
    print(
        f'\nwith {FLOOD_READS} reads sent just before: cancel answered in {cancel_sec:.3f} s '
        f'(reads: {dict(counts[0])}), stop in {stop_sec:.3f} s (reads: {dict(counts[1])}); '
        f'a read alone {idle_sec:.3f} s'
    )
    assert cancel.status_code == 200 and cancel.json()['status'] == 'DONE', cancel.text
    assert stop.status_code == 200 and stop.json()['status'] == 'DONE', stop.text
    assert http.get('/api/tasks/to-cancel').json()['status'] == 'CANCELED'
    assert http.get('/api/tasks/to-stop').json()['status'] == 'CANCELED'
    assert cancel_sec < CONTROL_ANSWER_MAX_SEC and stop_sec < CONTROL_ANSWER_MAX_SEC
    # each client has MAX_READS_PER_CLIENT reads in flight at most: the rest are refused at once
    for count in counts:
        assert set(count) == {200, 429} and count[200] >= MAX_READS_PER_CLIENT, count
    refused = next(body for status, body in cancel_reads if status == 429)
    assert check(json.loads(refused), 'error')['error']['code'] == 'too_many_requests'
