"""The adapter's start: its nice value; the node's declared tasks are asked again until the
start's deadline, as a newcomer can find the node's parameter services seconds after its action
(seen on a loaded machine: more than the client's 5 s, and the adapter died with a traceback);
no Task Manager within the wait: exit 3, for a new process."""

import subprocess
import sys
import time
from typing import Any

import pytest

from task_manager.core.errors import TaskManagerUnavailable
from task_manager.cpu_priority import GATEWAY_NICENESS
from task_manager.process_setup import EXIT_START_AGAIN
from task_manager_vda5050.main import _arguments, _declared_tasks
from task_manager_vda5050.mapping import DEMO_MAPPING

DECLARED = [{'task_name': 'navigate', 'blocking': True}]


class ParameterServicesFoundLate:
    """Stands for TaskManagerClient.declared_tasks: unavailable the first `misses` times."""

    def __init__(self, misses: int) -> None:
        self.misses = misses
        self.asked = 0

    def declared_tasks(self) -> list[dict[str, Any]]:
        self.asked += 1
        if self.asked <= self.misses:
            raise TaskManagerUnavailable('/task_manager/list_parameters is not available')
        return DECLARED


def test_declared_tasks_found_late_are_read_before_the_deadline() -> None:
    client = ParameterServicesFoundLate(misses=2)
    assert _declared_tasks(client, time.monotonic() + 60) == DECLARED  # type: ignore[arg-type]
    assert client.asked == 3


def test_past_the_deadline_the_last_error_is_raised() -> None:
    client = ParameterServicesFoundLate(misses=10**6)
    with pytest.raises(TaskManagerUnavailable, match='list_parameters is not available'):
        _declared_tasks(client, time.monotonic() + 0.05)  # type: ignore[arg-type]


REQUIRED = ['--manufacturer', 'acme', '--serial-number', 'r1', '--mapping', 'mapping.yaml']


def test_the_adapter_runs_at_nice_10_unless_told() -> None:
    assert _arguments(REQUIRED).nice == GATEWAY_NICENESS
    assert _arguments([*REQUIRED, '--nice', '0']).nice == 0


def test_a_nice_value_out_of_range_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stopped:
        _arguments([*REQUIRED, '--nice', '20'])
    assert stopped.value.code == 2
    assert '--nice: 20 is not between 0 and 19' in capsys.readouterr().err


NO_TASK_MANAGER = """
import sys
from task_manager_vda5050 import main
main.TASK_MANAGER_WAIT_SEC = 1.0
sys.exit(main.main({argv!r}))
"""


@pytest.mark.ros
def test_no_task_manager_within_the_wait_exits_3_for_a_new_process() -> None:
    """None answered (or, as a newcomer's participant now and then, not all of it): exit 3,
    which its supervisor (and the launchers) answer with a new process."""
    argv = [
        *REQUIRED[:-1],
        str(DEMO_MAPPING),
        '--broker-url',
        'mqtt://r1@127.0.0.1:1',
        '--nice',
        '0',
    ]
    ended = subprocess.run(
        [sys.executable, '-c', NO_TASK_MANAGER.format(argv=argv)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert ended.returncode == EXIT_START_AGAIN, ended.stderr
    assert 'task-manager-vda5050: no Task Manager answered' in ended.stderr
