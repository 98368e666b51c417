"""The gateways' requests as client calls: one function per request document of the protocol,
used by the web gateway and the MQTT bridge alike, so that both ask the Task Manager the same
thing for the same document. They block: call them from a worker thread."""

from task_manager.client import Subtask, TaskHandle, TaskManagerClient, TaskResult
from task_manager.protocol import models


def start_task(
    client: TaskManagerClient, request: models.StartTask, *, task_id: str, source: str
) -> TaskHandle:
    """Start the task the request names, with this id (empty: one is generated) and source."""
    return client.start_task(request.task_name, request.task_data, task_id=task_id, source=source)


def start_mission(
    client: TaskManagerClient, request: models.StartMission, *, task_id: str, source: str
) -> tuple[TaskHandle, list[str]]:
    """Start system/mission with the request's subtasks; its handle and the subtasks' ids."""
    subtasks = [
        Subtask(s.task_name, s.task_data, s.allow_skipping, s.task_id) for s in request.subtasks
    ]
    return client.start_mission(subtasks, task_id=task_id, source=source)


def cancel_tasks(
    client: TaskManagerClient, request: models.CancelTasks, *, source: str
) -> TaskResult:
    """system/cancel_task for the request's ids; its result."""
    return client.cancel_tasks(request.task_ids, source=source)
