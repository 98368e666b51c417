"""The documents a robot's bridge sends (docs/fleet-mqtt.md), made from the protocol's models,
as a simulated robot sends them."""

from collections.abc import Sequence
from datetime import UTC, datetime
from typing import Any

from task_manager.protocol import mqtt
from task_manager.protocol.models import DeclaredTask, Task

FINAL_STATUSES = ('DONE', 'ERROR', 'CANCELED')
GOAL_SCHEMA = {
    'type': 'object',
    'properties': {'order': {'type': 'integer', 'minimum': -2147483648, 'maximum': 2147483647}},
    'additionalProperties': False,
}
"""The task_data schema of the simulated tasks (a Fibonacci goal's)."""
Document = dict[str, Any]


def iso(moment: datetime) -> str:
    """ISO 8601 in UTC with a Z, as the bridge (and pydantic) write a time."""
    return moment.astimezone(UTC).isoformat().replace('+00:00', 'Z')


def declared(task_name: str, blocking: bool = False, resources: Sequence[str] = ()) -> Document:
    """A DeclaredTask document, as a bridge declares a Fibonacci action task."""
    task = {
        'task_name': task_name,
        'msg_interface': 'test_msgs/action/Fibonacci',
        'topic': f'/{task_name}',
        'blocking': blocking,
        'resources': list(resources),
        'goal_schema': GOAL_SCHEMA,
    }
    return DeclaredTask.model_validate(task).model_dump(mode='json')


def connection(robot_id: str, state: str, task_manager_connected: bool = True) -> Document:
    """A Connection document, stamped now."""
    document = {
        'robot_id': robot_id,
        'connection_state': state,
        'timestamp': iso(datetime.now(UTC)),
        'task_manager_connected': task_manager_connected,
    }
    return mqtt.Connection.model_validate(document).model_dump(mode='json')


def task_list(tasks: list[Document], omitted: int = 0) -> Document:
    """A document of a list of tasks (`active_tasks`, or the declared `tasks`), stamped now."""
    return {'timestamp': iso(datetime.now(UTC)), 'tasks': tasks, 'omitted': omitted}


def task_template(task_name: str, status: str) -> Document:
    """A Task document of the protocol's model (`task_id` and stamps to be set): a result
    for a final status, else a running task with its feedback."""
    ended = status in FINAL_STATUSES
    task = {
        'task_id': '-',
        'task_name': task_name,
        'source': 'CLOUD',
        'status': status,
        'duration_sec': 1.0 if ended else None,
        'result': {'sequence': [0, 1, 1]} if ended else None,
        'feedback': None if ended else {'partial_sequence': [0, 1]},
    }
    return Task.model_validate(task).model_dump(mode='json')
