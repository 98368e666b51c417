"""The Task Manager with one fault injected, as a bug of ours would raise it, for tests.

`python -m task_manager.testing.faulty_node STEP task-manager --ros-args --params-file F` (a
wrapper of `task-manager`, as NodeProcess takes one) runs the node in this process as
`task-manager` does, except that the first call of STEP raises InjectedFaultError. The steps are
those the node takes once a task's goal is on its server (and the deadline timer's callback):
a failure at any of them must neither free the goal from tracking nor stop the node.
"""

import importlib
import sys
from collections.abc import Callable
from typing import Any

# key: step, value: (module, class, method) whose first call raises
STEPS = {
    'action_execution': ('task_manager.ros.running.action_runner', 'ActionExecution', '__init__'),
    'server_watch': ('task_manager.ros.running.server_watch', 'ServerWatch', 'track'),
    'mark_started': ('task_manager.core.task', 'TaskRecord', 'mark_started'),
    'started_event': ('task_manager.ros.recording.task_events', 'TaskEventStream', 'started'),
    'attach': ('task_manager.ros.running.attempts', 'Attempts', 'attach'),
    'timeouts': ('task_manager.ros.running.attempts', 'Attempts', 'arm_timeouts'),
    'deadline_timer': ('task_manager.ros.running.deadline_timer', 'DeadlineTimer', '_on_timer'),
}
READY_LINE = 'fault injected at '


class InjectedFaultError(RuntimeError):
    """The fault a test asked for."""


def inject(step: str) -> None:
    """Make the first call of `step` raise InjectedFaultError."""
    module_name, class_name, method_name = STEPS[step]
    owner = getattr(importlib.import_module(module_name), class_name)
    original: Callable[..., Any] = getattr(owner, method_name)
    calls = [0]

    def faulty(*args: Any, **kwargs: Any) -> Any:
        calls[0] += 1
        if calls[0] == 1:
            raise InjectedFaultError(f'injected at {step}')
        return original(*args, **kwargs)

    setattr(owner, method_name, faulty)


def main() -> int:
    step, args = sys.argv[1], [sys.argv[0], *sys.argv[3:]]  # argv[2]: the node's executable
    from task_manager.process_setup import block_stop_signals
    from task_manager.ros.main import main as run_node

    # blocked before the node's modules start threads, as task-manager does (see ros/main.py)
    block_stop_signals()
    inject(step)
    print(READY_LINE + step, flush=True)
    return run_node(args)


if __name__ == '__main__':
    sys.exit(main())
