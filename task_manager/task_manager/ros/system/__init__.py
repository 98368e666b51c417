"""The tasks built into the Task Manager: system/mission, cancel_task, stop, wait, pause,
resume, schedule, unschedule and enable_schedule; system/confirm (confirm.py) is made by the
node, which also serves its answers."""

from rclpy.node import Node

from task_manager.ros.running.dispatcher import TaskDispatcher
from task_manager.ros.running.execution import TaskRunner
from task_manager.ros.running.scheduler import TaskScheduler
from task_manager.ros.system.cancel import CancelTasksRunner, StopTasksRunner
from task_manager.ros.system.mission import MissionRunner
from task_manager.ros.system.pause import PauseTasksRunner, ResumeTasksRunner
from task_manager.ros.system.reprioritize import ReprioritizeTasksRunner
from task_manager.ros.system.schedules import (
    EnableSchedulesRunner,
    ScheduleTaskRunner,
    UnscheduleRunner,
)
from task_manager.ros.system.wait import WaitRunner

__all__ = ['create_system_runners']


def create_system_runners(
    node: Node, dispatcher: TaskDispatcher, scheduler: TaskScheduler
) -> list[TaskRunner]:
    """One runner per system task name (system/cancel_tasks is an alias of cancel_task)."""
    return [
        MissionRunner(node, dispatcher),
        CancelTasksRunner(node, dispatcher, alias=False),
        CancelTasksRunner(node, dispatcher, alias=True),
        StopTasksRunner(node, dispatcher),
        WaitRunner(node),
        PauseTasksRunner(node, dispatcher),
        ResumeTasksRunner(node, dispatcher),
        ReprioritizeTasksRunner(node, dispatcher),
        ScheduleTaskRunner(node, dispatcher, scheduler),
        UnscheduleRunner(node, scheduler),
        EnableSchedulesRunner(node, scheduler),
    ]
