"""The gateways' requests as client calls: one function per request document of the protocol,
used by the web gateway and the MQTT bridge alike, so that both ask the Task Manager the same
thing for the same document. They block: call them from a worker thread."""

from typing import Any

from task_manager.client import Decision, Subtask, TaskHandle, TaskManagerClient, TaskResult
from task_manager.protocol import models

# the fields of a start's options: the same names as the client's keywords
OPTION_FIELDS = frozenset(
    {'priority', 'on_conflict', 'timeout_sec', 'queue_timeout_sec', 'feedback_timeout_sec'}
)


def options_of(request: models.StartTask | models.StartMission) -> dict[str, Any]:
    """The options a start gives (priority, on_conflict, timeouts), as the client's keywords;
    those left out take the task's declaration."""
    return request.model_dump(include=set(OPTION_FIELDS), exclude_none=True)


def start_task(
    client: TaskManagerClient, request: models.StartTask, *, task_id: str, source: str
) -> TaskHandle:
    """Start the task the request names, with this id (empty: one is generated), source and
    the request's options."""
    return client.start_task(
        request.task_name,
        request.task_data,
        task_id=task_id,
        source=source,
        **options_of(request),
    )


def start_mission(
    client: TaskManagerClient, request: models.StartMission, *, task_id: str, source: str
) -> tuple[TaskHandle, list[str]]:
    """Start system/mission with the request's subtasks; its handle and the subtasks' ids."""
    subtasks = [
        Subtask(s.task_name, s.task_data, s.allow_skipping, s.task_id) for s in request.subtasks
    ]
    return client.start_mission(subtasks, task_id=task_id, source=source, **options_of(request))


def cancel_tasks(
    client: TaskManagerClient, request: models.CancelTasks, *, source: str
) -> TaskResult:
    """system/cancel_task for the request's ids; its result."""
    return client.cancel_tasks(request.task_ids, source=source)


def reprioritize(
    client: TaskManagerClient, request: models.Reprioritize, *, source: str
) -> TaskResult:
    """system/reprioritize of the request's ids; its result."""
    return client.reprioritize(request.task_ids, request.priority, source=source)


def why(client: TaskManagerClient, task_id: str) -> list[Decision] | None:
    """Every decision taken about a task, oldest first; None when the Task Manager knows no
    such task (neither active nor in its history)."""
    states = client.task_states([task_id])
    return states[0].decisions if states else None
