"""Two test runs on one machine never share a ROS domain (task_manager.testing.domains)."""

import os
import subprocess
import sys

from task_manager.testing.domains import DOMAINS_PER_RUN, RUN_GROUPS, claim_run_domains

HOLD = (
    'import sys; from task_manager.testing.domains import claim_run_domains; '
    'print(claim_run_domains(int(sys.argv[1])), flush=True); sys.stdin.read()'
)


def test_a_group_another_process_holds_is_skipped_and_freed_when_it_ends() -> None:
    start = os.getpid() + 7
    holder = subprocess.Popen(
        [sys.executable, '-c', HOLD, str(start)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None
        held = int(holder.stdout.readline())
        mine = claim_run_domains(held // DOMAINS_PER_RUN)
        assert mine != held
        assert 1 <= mine <= RUN_GROUPS * DOMAINS_PER_RUN
        assert (mine - 1) % DOMAINS_PER_RUN == 0
    finally:
        holder.communicate('', timeout=10)
    again = subprocess.run(
        [sys.executable, '-c', HOLD, str(held // DOMAINS_PER_RUN)],
        input='',
        text=True,
        capture_output=True,
        timeout=10,
        check=True,
    )
    assert int(again.stdout) == held
