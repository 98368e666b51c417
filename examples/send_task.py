"""Start one task and print its result: navigate the demo robot (run `make run` first).

.venv/bin/python examples/send_task.py [x] [y]
"""

import sys

from task_manager import TaskManagerClient


def main() -> int:
    x, y = (float(v) for v in (sys.argv[1:3] if len(sys.argv) > 2 else (1.0, 0.5)))
    with TaskManagerClient('example_send_task') as client:
        client.wait_until_available()
        handle = client.start_task(
            'navigation/navigate_to_pose', {'x': x, 'y': y}, source='example'
        )
        print(f'started {handle.task_id}')
        result = handle.result(timeout_sec=120.0)
        print(f'{result.status}: {result.result}')
        return 0 if result.ok else 1


if __name__ == '__main__':
    sys.exit(main())
