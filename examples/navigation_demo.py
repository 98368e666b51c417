"""The original Task Manager's navigation demo, on the simulated robot (run `make run` first).

1. A navigation task starts.
2. While the robot drives, a spin task starts: both are blocking, so the spin cancels
   the navigation (which ends CANCELED).
3. Once the spin is done, a mission of four navigations with spins in between runs.

    .venv/bin/python examples/navigation_demo.py
"""

import sys

from task_manager import Subtask, TaskManagerClient, TaskStatus

NAVIGATE = 'navigation/navigate_to_pose'
SPIN = 'navigation/spin'
CORNERS = [(1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.0, 0.0)]
TIMEOUT_SEC = 300.0


def main() -> int:
    with TaskManagerClient('example_navigation_demo') as client:
        client.wait_until_available()
        navigation = client.start_task(NAVIGATE, {'x': 3.0, 'y': 0.0}, source='example')
        print(f'1. navigating: {navigation.task_id}')
        spin = client.run_task(SPIN, {'angle': 3.14}, source='example', timeout_sec=TIMEOUT_SEC)
        cancelled = navigation.result(TIMEOUT_SEC)
        print(f'2. spin {spin.status}; the navigation it pre-empted: {cancelled.status}')
        subtasks = []
        for x, y in CORNERS:
            subtasks += [Subtask(NAVIGATE, {'x': x, 'y': y}), Subtask(SPIN, {'angle': 1.57})]
        mission, _ = client.start_mission(subtasks[:-1], source='example')
        result = mission.result(TIMEOUT_SEC)
        print(f'3. mission of {len(subtasks) - 1} subtasks: {result.status}')
        ok = spin.ok and cancelled.status is TaskStatus.CANCELED and result.ok
        return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
