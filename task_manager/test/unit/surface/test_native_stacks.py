"""The watcher of a test process's deadlines (testing.native_stacks): a deadline passed dumps
the parent once, one disarmed in time dumps nothing, and it ends when its parent's pipe closes.
Commands that print what they were given stand in for py-spy and gdb."""

import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from task_manager.testing.native_stacks import OFF, PID, every_thread, watch

WAIT_SEC = 5.0
SLEEPER = (
    'import threading, time\n'
    'threading.Thread(target=time.sleep, args=(60,), daemon=True).start()\n'
    'print("ready", flush=True)\n'
    'time.sleep(60)\n'
)
STAND_INS = [
    [sys.executable, '-c', 'import sys; print("dumped", *sys.argv[1:])', '--pid', PID],
    [sys.executable, '-c', 'import sys; print("every thread of", *sys.argv[1:])', PID],
]


def _watching(out: Path) -> tuple[threading.Thread, int]:
    """The watcher in a thread, reading a pipe (closed with the test's process); the pipe's
    write end."""
    read_end, write_end = os.pipe()
    thread = threading.Thread(target=watch, args=(read_end, out, STAND_INS, 4242), daemon=True)
    thread.start()
    return thread, write_end


def _wait_for_text(out: Path) -> str:
    deadline = time.monotonic() + WAIT_SEC
    while time.monotonic() < deadline:
        if out.exists() and 'every thread of 4242' in out.read_text():
            return out.read_text()
        threading.Event().wait(0.02)
    return out.read_text() if out.exists() else ''


def test_a_deadline_passed_dumps_the_parent_once_and_the_pipe_closing_ends_the_watcher(
    tmp_path: Path,
) -> None:
    out = tmp_path / 'stacks.txt'
    thread, commands = _watching(out)
    os.write(commands, b'0.05\n')
    text = _wait_for_text(out)
    os.close(commands)
    thread.join(WAIT_SEC)

    assert not thread.is_alive()
    assert text.startswith('native stacks of process 4242, ')
    assert text.count('dumped --pid 4242') == 1
    assert text.count('every thread of 4242') == 1  # after the first: one tracer at a time
    assert text.index('every thread of 4242') > text.index('dumped --pid')


def test_a_test_that_ends_before_its_deadline_dumps_nothing(tmp_path: Path) -> None:
    out = tmp_path / 'stacks.txt'
    thread, commands = _watching(out)
    os.write(commands, f'0.3\n{OFF}\n'.encode())
    os.write(commands, b'60\n')  # the next test, far from its deadline
    threading.Event().wait(0.6)  # past the first deadline: the input under test is time
    os.close(commands)
    thread.join(WAIT_SEC)

    assert not thread.is_alive()
    assert not out.exists()


@pytest.mark.skipif(shutil.which('gdb') is None, reason='gdb is not installed')
def test_every_thread_gives_the_native_stack_of_each_thread_of_a_live_process() -> None:
    """What a test prints of a process it aborts (NodeProcess.abort): a thread waiting in C is
    shown in C (py-spy would list only the Python threads)."""
    child = subprocess.Popen([sys.executable, '-c', SLEEPER], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None and child.stdout.readline() == 'ready\n'
        stacks = every_thread(child.pid)
    finally:
        child.kill()
        child.wait()

    assert stacks.count('Thread ') >= 2  # the main thread and the one it started
    assert 'sleep' in stacks
