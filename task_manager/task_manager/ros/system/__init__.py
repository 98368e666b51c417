"""The tasks built into the Task Manager: system/mission, cancel_task, stop, wait, pause,
resume, schedule, unschedule and enable_schedule; system/confirm (confirm.py) is made by the
node, which also serves its answers."""

from typing import Protocol

from rclpy.node import Node

from task_manager.ros.running.execution import TaskCatalog, TaskRunner
from task_manager.ros.running.protocols import TaskPausing, TaskReprioritizing
from task_manager.ros.running.scheduler import TaskScheduler
from task_manager.ros.system.cancel import CancelledTasks, CancelTasksRunner, StopTasksRunner
from task_manager.ros.system.mission import MissionRunner, Subtasks
from task_manager.ros.system.pause import PauseTasksRunner, ResumeTasksRunner
from task_manager.ros.system.reprioritize import ReprioritizeTasksRunner
from task_manager.ros.system.schedules import (
    EnableSchedulesRunner,
    ScheduleTaskRunner,
    UnscheduleRunner,
)
from task_manager.ros.system.wait import WaitRunner

__all__ = ['SystemTasks', 'create_system_runners']


class SystemTasks(Subtasks, CancelledTasks, Protocol):
    """What the system tasks need of the active tasks (the dispatcher)."""


def create_system_runners(
    node: Node,
    tasks: SystemTasks,
    pauses: TaskPausing,
    priorities: TaskReprioritizing,
    catalog: TaskCatalog,
    scheduler: TaskScheduler,
) -> list[TaskRunner]:
    """One runner per system task name (system/cancel_tasks is an alias of cancel_task)."""
    return [
        MissionRunner(node, tasks, pauses, catalog),
        CancelTasksRunner(node, tasks, alias=False),
        CancelTasksRunner(node, tasks, alias=True),
        StopTasksRunner(node, tasks),
        WaitRunner(node),
        PauseTasksRunner(node, pauses),
        ResumeTasksRunner(node, pauses),
        ReprioritizeTasksRunner(node, priorities),
        ScheduleTaskRunner(node, catalog, scheduler),
        UnscheduleRunner(node, scheduler),
        EnableSchedulesRunner(node, scheduler),
    ]
