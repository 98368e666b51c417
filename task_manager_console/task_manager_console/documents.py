"""The console's own JSON documents: its requests beyond the robot's (a start on "any robot")
and its answers. A robot's documents (a start, a mission, a cancel, ...) are the protocol's
(`task_manager.protocol.models`), sent on to the robot as they are."""

from typing import Any

from pydantic import BaseModel, Field

from task_manager.core.names import IDS_MAX
from task_manager.protocol import models


class FleetStart(models.StartTask):
    """POST /api/fleet/start: a start on the robot the console chooses."""

    robots: list[models.Name] | None = Field(
        None,
        min_length=1,
        max_length=IDS_MAX,
        description='The candidates, by id; left out: every robot on the broker.',
    )


class RobotStarted(BaseModel):
    """A task or mission started on a robot: the robot's reply."""

    robot_id: str
    task_id: str
    subtask_ids: list[str] = Field(default_factory=list, description='Of a mission.')
    duplicate: bool = Field(False, description='The robot knew this task id: nothing started.')
    task: models.Task | None = Field(None, description='The task, as the robot knows it.')


class FleetStarted(RobotStarted):
    """A task started on "any robot": on which one, why, and why not each other candidate."""

    reason: str = Field(examples=['robot2 is ONLINE, declares dock, its resources ... are free'])
    others: dict[str, str] = Field(
        default_factory=dict,
        description='Key: another candidate, value: why it was not chosen.',
        examples=[{'robot1': 'its resources for dock are busy', 'robot3': 'OFFLINE'}],
    )


class RobotAnswer(BaseModel):
    """One robot's answer to STOP ALL: its system/stop task, or why it was not stopped."""

    robot_id: str
    ok: bool
    task: models.Task | None = None
    error: models.ErrorDetail | None = None


class StopAll(BaseModel):
    """POST /api/fleet/stop: each robot's answer, by robot id."""

    answers: list[RobotAnswer]


def started(robot_id: str, reply: dict[str, Any]) -> dict[str, Any]:
    """A RobotStarted document of a robot's reply to a start."""
    return {
        'robot_id': robot_id,
        'task_id': reply.get('task_id', ''),
        'subtask_ids': reply.get('subtask_ids') or [],
        'duplicate': bool(reply.get('duplicate')),
        'task': reply.get('task'),
    }
