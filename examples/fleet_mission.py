"""Send a photo mission to every robot of a fleet through the broker, and print its progress
(run `make fleet` first; it prints this command with the broker URL).

.venv/bin/python examples/fleet_mission.py --broker-url mqtt://cloud@127.0.0.1:PORT \
    --password-file .ros/task_manager/fleet/cloud/mqtt_password
"""

import argparse
import sys
from pathlib import Path
from typing import Any

from task_manager_mqtt.fleet_client import FleetClient
from task_manager_mqtt.fleet_types import FleetError

ROBOTS = ['robot1', 'robot2', 'robot3']
TIMEOUT_SEC = 300.0


def mission(n: int) -> list[dict[str, Any]]:
    """Out to a spot of its own, a photo there, and back."""
    return [
        {'task_name': 'navigation/navigate_to_pose', 'task_data': {'x': 1.0, 'y': float(n)}},
        {'task_name': 'camera/take_photo', 'task_data': {'camera': 'front'}},
        {'task_name': 'navigation/navigate_to_pose', 'task_data': {'x': 0.0, 'y': 0.0}},
    ]


def show(robot_id: str, event: dict[str, Any]) -> None:
    task = event['task']
    if task['task_name'] != 'system/mission' and event['event'] in ('STARTED', 'ENDED'):
        status = task['status'] if event['event'] == 'ENDED' else 'started'
        print(f'  [{robot_id}] {task["task_name"]:28} {status}', flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--broker-url', required=True, help='mqtt://cloud@HOST:PORT')
    parser.add_argument(
        '--password-file', type=Path, help="the file holding the cloud account's password"
    )
    parser.add_argument('--robots', default=','.join(ROBOTS), help='comma-separated ids')
    options = parser.parse_args()
    robots = options.robots.split(',')
    password = options.password_file.read_text().strip() if options.password_file else ''
    with FleetClient(
        options.broker_url, events=True, source='fleet_example', password=password
    ) as fleet:
        if not fleet.wait_online(robots, timeout_sec=30.0):
            print(f'not every robot of {robots} is online: {list(fleet.robots)}')
            return 1
        fleet.on_event(show)
        started = [fleet.start_mission(r, mission(n)) for n, r in enumerate(robots)]
        for task in started:
            print(f'{task.robot_id}: mission {task.accepted()["task_id"]} accepted')
        failed = 0
        for task in started:
            try:
                result = task.result(TIMEOUT_SEC)
            except FleetError as error:
                print(f'{task.robot_id}: {error}')
                failed += 1
                continue
            print(f'{task.robot_id}: mission {result["status"]} in {result["duration_sec"]:.1f} s')
            failed += result['status'] != 'DONE'
        return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
