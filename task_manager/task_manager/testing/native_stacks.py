"""A watcher process that writes the native stacks of its parent, a test process, when a test
runs past its deadline: faulthandler's watchdog (conftest.py) prints only the Python stacks, and
a process stuck inside Fast DDS is stuck in C, where the lock cycle is to be read.

The parent writes each test's deadline, in seconds from now, as a line to the watcher's stdin,
and `off` when the test ends; at a deadline passed, the watcher appends to its file, once,
`py-spy dump --native` of the parent (its Python threads, their Python frames among the C ones)
and, where gdb is installed, gdb's backtrace of every thread: Fast DDS's own threads (its timer
thread, its listeners), which py-spy does not list, hold the other end of a lock cycle. It ends
when its stdin closes (the parent has gone).

Run as `python -m task_manager.testing.native_stacks FILE`.
"""

import os
import select
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import TextIO

DUMP_TIMEOUT_SEC = 60.0
OFF = 'off'
PID = '{pid}'
"""Where a dump's command takes the parent's process id."""
GDB_EVERY_THREAD = ['-batch', '-nx', '-ex', 'set pagination off', '-ex', 'thread apply all bt']


def py_spy() -> str | None:
    """The py-spy beside this interpreter (the venv's), else on PATH; None without one."""
    beside = Path(sys.executable).with_name('py-spy')
    return str(beside) if beside.exists() else shutil.which('py-spy')


def _gdb_every_thread(pid: str) -> list[str] | None:
    """gdb's command for the backtrace of every thread of process `pid`; None without gdb."""
    gdb = shutil.which('gdb')
    return None if gdb is None else [gdb, '-p', pid, *GDB_EVERY_THREAD]


def dump_commands() -> list[list[str]]:
    """py-spy's dump and gdb's, those of them installed (PID where the process id goes)."""
    commands = []
    if (spy := py_spy()) is not None:
        commands.append([spy, 'dump', '--native', '--pid', PID])
    if (gdb := _gdb_every_thread(PID)) is not None:
        commands.append(gdb)
    return commands


def every_thread(pid: int) -> str:
    """gdb's backtrace of every thread of process `pid` (what it printed; '' without gdb)."""
    command = _gdb_every_thread(str(pid))
    if command is None:
        return ''
    try:
        done = subprocess.run(
            command,
            stdin=subprocess.DEVNULL,
            capture_output=True,
            text=True,
            timeout=DUMP_TIMEOUT_SEC,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired) as error:
        return f'no native stacks: {error}'
    return done.stdout + done.stderr


def watch(commands: int, out: Path, dumps: list[list[str]], parent: int) -> None:
    """Follow the deadlines on the file descriptor `commands` until it closes; at one passed,
    run each of `dumps` on `parent`, one after the other (a process takes one tracer at a time).
    Read unbuffered: a line left in a buffer would be a deadline missed."""
    deadline: float | None = None
    pending = b''
    while True:
        wait = None if deadline is None else max(deadline - time.monotonic(), 0.0)
        if select.select([commands], [], [], wait)[0]:
            chunk = os.read(commands, 4096)
            if not chunk:
                return
            *lines, pending = (pending + chunk).split(b'\n')
            for line in lines:
                command = line.decode().strip()
                deadline = None if command == OFF else time.monotonic() + float(command)
        elif deadline is not None:
            deadline = None
            with out.open('a', encoding='utf-8') as file:
                file.write(f'native stacks of process {parent}, {time.ctime()}:\n')
                for dump in dumps:
                    _run_dump([part.replace(PID, str(parent)) for part in dump], file)


def _run_dump(command: list[str], file: TextIO) -> None:
    file.write(f'$ {" ".join(command)}\n')
    file.flush()
    try:
        subprocess.run(
            command,
            stdin=subprocess.DEVNULL,
            stdout=file,
            stderr=subprocess.STDOUT,
            timeout=DUMP_TIMEOUT_SEC,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired) as error:
        file.write(f'no native stacks: {error}\n')


class NativeStacks:
    """The parent's end: a watcher started on first use when py-spy is there, else nothing."""

    def __init__(self, out: Path) -> None:
        self._out = out
        self._watcher: subprocess.Popen[str] | None = None
        self._tried = False

    def arm(self, after_sec: float) -> None:
        """Dump this process's native stacks `after_sec` from now, unless disarmed first."""
        self._send(f'{after_sec:.3f}')

    def disarm(self) -> None:
        self._send(OFF)

    def _send(self, command: str) -> None:
        watcher = self._start()
        if watcher is None or watcher.stdin is None:
            return
        try:
            watcher.stdin.write(command + '\n')
            watcher.stdin.flush()
        except OSError:  # the watcher has gone: the tests go on without it
            self._watcher = None

    def _start(self) -> 'subprocess.Popen[str] | None':
        if self._tried:
            return self._watcher
        self._tried = True
        if not dump_commands():
            return None
        self._out.parent.mkdir(parents=True, exist_ok=True)
        self._watcher = subprocess.Popen(
            [sys.executable, '-m', __name__, str(self._out)],
            stdin=subprocess.PIPE,
            text=True,
        )
        return self._watcher


def main() -> int:
    dumps = dump_commands()
    if dumps:
        watch(sys.stdin.fileno(), Path(sys.argv[1]), dumps, os.getppid())
    return 0


if __name__ == '__main__':
    sys.exit(main())
