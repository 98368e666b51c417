"""ROS domains for a test run, claimed on the machine so two runs never share one.

A run takes a group of DOMAINS_PER_RUN consecutive domains: its pytest-xdist workers the first
four (WORKERS), then those of tests that start nodes in domains of their own. The claim is an
abstract Unix socket bound for the life of the process that claimed it: no file is written, and
the kernel releases it however the run ends (SIGKILL included).
"""

import os
import socket

# offsets in a run's group
WORKERS = range(0, 4)
# the console tests' two demo robots, two for each worker: two test files that start them may
# run at once, in two workers
CONSOLE_ROBOTS_PER_WORKER = 2
CONSOLE_ROBOTS = range(WORKERS.stop, WORKERS.stop + CONSOLE_ROBOTS_PER_WORKER * len(WORKERS))
# two Task Managers and a third that is refused
HISTORY_PER_DOMAIN = range(CONSOLE_ROBOTS.stop, CONSOLE_ROBOTS.stop + 3)
DOMAINS_PER_RUN = HISTORY_PER_DOMAIN.stop  # 15
RUN_GROUPS = 6  # domains 1-90; the fleet test adds 120 to its run's first domain (max 232)
_CLAIM_PREFIX = '\0task_manager_test_domains_'

_claims: list[socket.socket] = []


def claim_run_domains(start: int) -> int:
    """The first domain of a free group, trying from group `start % RUN_GROUPS` on.

    The claim lasts as long as this process. Raises RuntimeError when every group is taken.
    """
    for step in range(RUN_GROUPS):
        group = (start + step) % RUN_GROUPS
        claim = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            claim.bind(f'{_CLAIM_PREFIX}{group}')
        except OSError:
            claim.close()
            continue
        _claims.append(claim)
        return 1 + group * DOMAINS_PER_RUN
    raise RuntimeError(f'all {RUN_GROUPS} groups of test ROS domains are taken by other runs')


def worker_index(worker: str) -> int:
    """Which of WORKERS a pytest-xdist worker (`gw0`...; the controller is gw0) is."""
    return int(worker.removeprefix('gw')) % len(WORKERS)


def worker_domain(first: int, worker: str) -> int:
    """The domain of a pytest-xdist worker."""
    return first + WORKERS[worker_index(worker)]


def run_domains(offsets: range) -> list[int]:
    """The domains at `offsets` in this run's group (its first domain is in the environment)."""
    first = int(os.environ['TASK_MANAGER_TEST_DOMAIN'])
    return [first + offset for offset in offsets]


def console_robot_domains() -> list[int]:
    """The two domains of this worker's console demo robots."""
    start = CONSOLE_ROBOTS.start + CONSOLE_ROBOTS_PER_WORKER * worker_index(
        os.environ.get('PYTEST_XDIST_WORKER', 'gw0')
    )
    return run_domains(range(start, start + CONSOLE_ROBOTS_PER_WORKER))
