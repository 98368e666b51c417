"""ROS domains for a test run, claimed on the machine so two runs never share one.

A run takes a group of DOMAINS_PER_RUN consecutive domains (its pytest-xdist workers the first
four, the console tests' demo robots the last two). The claim is an abstract Unix socket bound
for the life of the process that claimed it: no file is written, and the kernel releases it
however the run ends (SIGKILL included).
"""

import socket

DOMAINS_PER_RUN = 6
RUN_GROUPS = 16  # domains 1-96; a fleet test adds 120 to its run's first domain (max 232)
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


def worker_domain(first: int, worker: str) -> int:
    """The domain of a pytest-xdist worker (`gw0`...; the controller is gw0)."""
    return first + int(worker.removeprefix('gw')) % 4
