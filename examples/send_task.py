"""Start one task, print its feedback and result: navigate the demo robot (`make run` first).

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
        for feedback in handle.feedback(timeout_sec=120.0):  # until the task ends
            print(f'  {feedback["distance_remaining"]:.2f} m to go')
        result = handle.result(timeout_sec=120.0)
        print(f'{result.status} after {result.duration}: {result.result}')
        return 0 if result.ok else 1


if __name__ == '__main__':
    sys.exit(main())
