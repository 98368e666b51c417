"""Print every change of the active tasks and every result, whoever started the tasks.

.venv/bin/python examples/track_active_tasks.py [seconds]   (Ctrl-C to stop)
"""

import sys

from task_manager import TaskManagerClient, TaskResult


def main() -> int:
    quiet_sec = float(sys.argv[1]) if len(sys.argv) > 1 else None
    with TaskManagerClient('example_tracker') as client:
        client.wait_until_available()
        print('watching /task_manager/active_tasks and /task_manager/results')
        try:
            for update in client.updates(timeout_sec=quiet_sec):
                if isinstance(update, TaskResult):
                    print(f'result  {update.task_name} {update.task_id}: {update.status}')
                else:
                    active = ', '.join(f'{t.task_name} ({t.status})' for t in update)
                    print(f'active  [{active}]')
        except KeyboardInterrupt:
            pass
    return 0


if __name__ == '__main__':
    sys.exit(main())
