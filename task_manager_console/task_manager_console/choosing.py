"""Which robot runs a task asked of "any robot": pure, from the robots' states.

A candidate must be ONLINE (reaching its Task Manager) and declare the task; among those, one
whose running tasks leave the task's resources free comes first, then the least loaded (fewest
active tasks), then the first by id. What a task holds is what its robot's Task Manager would
say (core/admission/claims.py), read from the robot's declared tasks: its declared `resources`,
the blocking slot if it is blocking, its one goal slot if it is not reentrant.
"""

from dataclasses import dataclass, field

from task_manager.core.admission.claims import implied_resources, task_slot
from task_manager_console.robots import Document, RobotState

HOLDING = ('IN_PROGRESS', 'PAUSED')
"""Statuses of active tasks that hold what they use (not QUEUED)."""


@dataclass(frozen=True)
class Choice:
    """The robot chosen (None: none can), why, and why not each other candidate."""

    robot_id: str | None
    reason: str
    others: dict[str, str] = field(default_factory=dict)
    """Key: another candidate's id, value: why it was not chosen."""


def choose_robot(
    task_name: str, candidates: list[RobotState], requested: list[str] | None = None
) -> Choice:
    """The robot of `candidates` (those of `requested` ids only, when given) to run
    `task_name`; a requested id that is no candidate is in `others` as unknown."""
    by_id = {robot.robot_id: robot for robot in candidates}
    others: dict[str, str] = {}
    if requested is not None:
        for robot_id in requested:
            if robot_id not in by_id:
                others[robot_id] = 'no such robot on the broker'
        pool = [by_id[i] for i in dict.fromkeys(requested) if i in by_id]
    else:
        pool = sorted(candidates, key=lambda robot: robot.robot_id)
    able: list[RobotState] = []
    for robot in pool:
        if not robot.online:
            others[robot.robot_id] = _why_offline(robot)
        elif not robot.declares(task_name):
            others[robot.robot_id] = f'does not declare {task_name}'
        else:
            able.append(robot)
    if not able:
        return Choice(None, f'no ONLINE robot declares {task_name}', others)
    ranked = sorted(able, key=lambda r: (not _free(r, task_name), len(r.active), r.robot_id))
    chosen = ranked[0]
    for robot in ranked[1:]:
        others[robot.robot_id] = _compared(robot, chosen, task_name)
    return Choice(chosen.robot_id, _reason(chosen, task_name), others)


def _free(robot: RobotState, task_name: str) -> bool:
    """Whether the task's resources are free on the robot: none of its active tasks that hold
    what they use holds one of them."""
    wanted = _held(robot, task_name)
    return not any(
        task.get('status') in HOLDING and wanted & _held(robot, str(task.get('task_name')))
        for task in robot.active
    )


def _held(robot: RobotState, task_name: str) -> frozenset[str]:
    """What a task of the robot holds while it runs, by its declaration (only its one goal
    slot if the robot declares no such task)."""
    declared: Document | None = next(
        (t for t in robot.tasks if t.get('task_name') == task_name), None
    )
    if declared is None:
        return frozenset({task_slot(task_name)})
    return implied_resources(
        task_name,
        declared.get('resources') or [],
        bool(declared.get('blocking')),
        bool(declared.get('reentrant')),
    )


def _reason(robot: RobotState, task_name: str) -> str:
    free = 'its resources for it are free' if _free(robot, task_name) else 'its resources are busy'
    return (
        f'{robot.robot_id} is ONLINE, declares {task_name}, {free}, '
        f'{len(robot.active)} active tasks'
    )


def _compared(robot: RobotState, chosen: RobotState, task_name: str) -> str:
    if not _free(robot, task_name) and _free(chosen, task_name):
        return f'its resources for {task_name} are busy'
    if len(robot.active) > len(chosen.active):
        return (
            f'busier: {len(robot.active)} active tasks, {chosen.robot_id} has {len(chosen.active)}'
        )
    return f'as able as {chosen.robot_id}, which comes first by id'


def _why_offline(robot: RobotState) -> str:
    if robot.silent and str(robot.connection_state) == 'ONLINE':
        return 'ONLINE but its bridge reaches no Task Manager'
    return f'{robot.connection_state}'
