"""The tests' OutputReader (shared with the fleet console's tests): a process's lines waited for
as they come, and an output that ended told from a wait that ran out; NodeProcess.stop of a
process that does not stop."""

import signal
import subprocess
import sys

import pytest

from task_manager.testing.output_reader import OutputReader
from task_manager.testing.process import NodeProcess

TIMEOUT_SEC = 10.0
SPEAKS_TWICE = "import sys; print('ready', flush=True); sys.stdin.readline(); print('bye')"
DEAF_TO_SIGINT = """
import signal, time
signal.signal(signal.SIGINT, signal.SIG_IGN)
def never_returning():
    print('ready', flush=True)
    time.sleep(60)
never_returning()
"""


def test_a_line_is_found_as_it_comes_and_none_once_the_output_ended_without_it() -> None:
    process = subprocess.Popen(
        [sys.executable, '-c', SPEAKS_TWICE],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert process.stdin is not None and process.stdout is not None
    reader = OutputReader(process.stdout)

    ready = reader.find('^rea', TIMEOUT_SEC)
    not_yet = reader.find('bye', 0.05)
    ended_while_running = reader.ended
    process.stdin.write('\n')
    process.stdin.close()
    bye = reader.find('bye', TIMEOUT_SEC)
    never = reader.find('never', TIMEOUT_SEC)
    reader.join(TIMEOUT_SEC)

    assert process.wait(TIMEOUT_SEC) == 0
    assert (ready, not_yet, ended_while_running) == ('ready', None, False)
    assert (bye, never, reader.ended) == ('bye', None, True)
    assert reader.lines == ['ready', 'bye']


def test_a_process_that_does_not_stop_is_aborted_with_its_stacks_printed(
    capsys: pytest.CaptureFixture[str],
) -> None:
    deaf = NodeProcess(
        None,
        command=[sys.executable, '-c', DEAF_TO_SIGINT],
        env={'PYTHONFAULTHANDLER': '1'},
    )
    deaf.wait_for_log('^ready$', TIMEOUT_SEC)

    with pytest.raises(subprocess.TimeoutExpired):
        deaf.stop(timeout_sec=0.5)

    assert deaf.process.returncode == -signal.SIGABRT
    printed = capsys.readouterr().out
    assert 'did not stop within 0.5 s of SIGINT; aborted, its output:' in printed
    assert 'in never_returning' in printed, printed
