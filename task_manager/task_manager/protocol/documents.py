"""Every JSON document of the protocol, by the name of its schema file."""

from pydantic import BaseModel

from task_manager.protocol.models import (
    CancelTasks,
    Decision,
    DeclaredTask,
    EnableSchedule,
    Error,
    HistoryQuery,
    Paused,
    PauseTasks,
    Reprioritize,
    Resumed,
    ResumeTasks,
    Schedule,
    Scheduled,
    ScheduleTask,
    Started,
    StartMission,
    StartTask,
    Task,
    TaskEvent,
)
from task_manager.protocol.mqtt import (
    ActiveTasks,
    Connection,
    DeadLetter,
    DeclaredTasks,
    Reply,
    RobotRequest,
)

# key: schema file stem, value: the model it documents
DOCUMENTS: dict[str, type[BaseModel]] = {
    'start_task': StartTask,
    'start_mission': StartMission,
    'cancel_tasks': CancelTasks,
    'reprioritize': Reprioritize,
    'pause_tasks': PauseTasks,
    'resume_tasks': ResumeTasks,
    'paused': Paused,
    'resumed': Resumed,
    'schedule_task': ScheduleTask,
    'scheduled': Scheduled,
    'enable_schedule': EnableSchedule,
    'schedule': Schedule,
    'history_query': HistoryQuery,
    'decision': Decision,
    'task': Task,
    'task_event': TaskEvent,
    'started': Started,
    'error': Error,
    'declared_task': DeclaredTask,
    'mqtt_request': RobotRequest,
    'mqtt_reply': Reply,
    'mqtt_connection': Connection,
    'mqtt_dead_letter': DeadLetter,
    'mqtt_active_tasks': ActiveTasks,
    'mqtt_tasks': DeclaredTasks,
}
