"""The tests' OutputReader (shared with the fleet console's tests): a process's lines waited for
as they come, and an output that ended told from a wait that ran out."""

import subprocess
import sys

from task_manager.testing.output_reader import OutputReader

TIMEOUT_SEC = 10.0
SPEAKS_TWICE = "import sys; print('ready', flush=True); sys.stdin.readline(); print('bye')"


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
