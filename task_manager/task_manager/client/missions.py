"""Missions as the client sends them: `Subtask`, and system/mission's task data."""

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from task_manager.client.message_values import json_text


@dataclass(frozen=True)
class Subtask:
    """One subtask of a mission; `task_data` is a dict or a JSON string."""

    task_name: str
    task_data: dict[str, Any] | str = field(default_factory=dict)
    allow_skipping: bool = False
    task_id: str = ''


def mission_task_data(subtasks: Sequence[Subtask], subtask_ids: Sequence[str]) -> dict[str, Any]:
    """The task data of system/mission (an empty subtask id: the Task Manager makes one)."""
    return {
        'subtasks': [
            {
                'task_id': subtask_id,
                'task_name': subtask.task_name,
                'task_data': json_text(subtask.task_data),
                'allow_skipping': subtask.allow_skipping,
            }
            for subtask, subtask_id in zip(subtasks, subtask_ids, strict=True)
        ]
    }
