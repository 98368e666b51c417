"""Start a mission and print how each subtask went (run `make run` first).

.venv/bin/python examples/send_mission.py
"""

import sys

from task_manager import Subtask, TaskManagerClient

MISSION = [
    Subtask('navigation/navigate_to_pose', {'x': 1.0, 'y': 0.0}),
    Subtask('camera/take_photo', {'camera': 'broken'}, allow_skipping=True),  # fails, skipped
    Subtask('camera/take_photo', {'camera': 'front'}),
    Subtask('navigation/navigate_to_pose', {'x': 0.0, 'y': 0.0}),
]


def main() -> int:
    with TaskManagerClient('example_send_mission') as client:
        client.wait_until_available()
        handle, subtask_ids = client.start_mission(MISSION, source='example')
        print(f'mission {handle.task_id} with subtasks {subtask_ids}')
        result = handle.result(timeout_sec=300.0)
        for row in result.result['mission_results']:
            skipped = ' (skipped)' if row['skipped'] else ''
            print(f'  {row["task_name"]:32} {row["task_status"]}{skipped}')
        print(f'mission {result.status}')
        return 0 if result.ok else 1


if __name__ == '__main__':
    sys.exit(main())
