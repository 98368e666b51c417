"""`python -m task_manager_demo.parent_death PID COMMAND...`: COMMAND dies with process PID.

Runs COMMAND (by exec, so it keeps this process id) after asking Linux to send it SIGTERM
when its parent dies, however the parent dies: SIGKILL included (PR_SET_PDEATHSIG). SIGTERM,
not SIGKILL, so that a ROS node still shuts down cleanly (the Task Manager cancels its tasks
on the robot). PID is the parent's id: if it died before the request was made, COMMAND is not
started at all. Elsewhere than on Linux, COMMAND just runs.
"""

import ctypes
import os
import signal
import sys

PR_SET_PDEATHSIG = 1
EXIT_PARENT_GONE = 1


def die_with_parent(command: list[str]) -> list[str]:
    """`command`, wrapped so that it receives SIGTERM when this process dies."""
    return [sys.executable, '-m', __spec__.name, str(os.getpid()), *command]


def _request_parent_death_signal() -> None:
    if not sys.platform.startswith('linux'):
        return
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0) != 0:
        error = ctypes.get_errno()
        raise OSError(error, f'prctl(PR_SET_PDEATHSIG): {os.strerror(error)}')


def main(argv: list[str]) -> int:
    parent, command = int(argv[0]), argv[1:]
    _request_parent_death_signal()
    if os.getppid() != parent:
        return EXIT_PARENT_GONE
    os.execvp(command[0], command)


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
