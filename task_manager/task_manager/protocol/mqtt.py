"""The MQTT documents: those of the topics under <prefix>/<robot_id>/ (see docs/fleet-mqtt.md).

They reuse the requests and answers of models.py, which both gateways speak.
"""

from datetime import datetime
from typing import Annotated, Literal

from pydantic import BaseModel, Field, RootModel

from task_manager.core.names import IDS_MAX
from task_manager.protocol.models import (
    NAME_MAX,
    CancelTasks,
    Confirmed,
    ConfirmTask,
    Decision,
    DeclaredTask,
    EnableSchedule,
    ErrorDetail,
    HistoryQuery,
    Name,
    Paused,
    PauseTasks,
    Reprioritize,
    Resumed,
    ResumeTasks,
    Schedule,
    Scheduled,
    ScheduleTask,
    StartMission,
    StartTask,
    Task,
    _Request,
)


class _Addressed(_Request):
    request_id: str = Field(
        min_length=1, max_length=NAME_MAX, description='Echoed in the reply, to match it.'
    )


class _Sourced(_Request):
    source: Name = Field('', max_length=NAME_MAX, description="Empty: the bridge's own name.")


class StartTaskRequest(StartTask, _Sourced, _Addressed):
    """`start_task`. Without a task_id, the task's id is the request_id, so that a request
    delivered twice is recognised and starts nothing the second time."""

    op: Literal['start_task']


class StartMissionRequest(StartMission, _Sourced, _Addressed):
    """`start_mission` (the mission's id defaults to the request_id, as for start_task)."""

    op: Literal['start_mission']


class CancelRequest(CancelTasks, _Addressed):
    """`cancel`: system/cancel_task of these ids."""

    op: Literal['cancel']


class StopRequest(_Addressed):
    """`stop`: system/stop."""

    op: Literal['stop']


class HistoryRequest(HistoryQuery, _Addressed):
    """`history`: ended tasks from the durable history."""

    op: Literal['history']


class ReprioritizeRequest(Reprioritize, _Addressed):
    """`reprioritize`: system/reprioritize of these ids."""

    op: Literal['reprioritize']


class WhyRequest(_Addressed):
    """`why`: every decision the Task Manager took about a task, active or ended."""

    op: Literal['why']
    task_id: Name = Field(min_length=1, max_length=NAME_MAX)


class PauseRequest(PauseTasks, _Addressed):
    """`pause`: system/pause of these ids."""

    op: Literal['pause']


class ResumeRequest(ResumeTasks, _Addressed):
    """`resume`: system/resume of these ids."""

    op: Literal['resume']


class ScheduleRequest(ScheduleTask, _Addressed):
    """`schedule`: system/schedule of a task or a mission (the fields of the web API's POST
    /api/schedules; created by the bridge's source)."""

    op: Literal['schedule']


class UnscheduleRequest(_Addressed):
    """`unschedule`: system/unschedule of one schedule; `unknown_schedule_id` if there is none."""

    op: Literal['unschedule']
    schedule_id: Name = Field(min_length=1, max_length=NAME_MAX)


class EnableSchedulesRequest(EnableSchedule, _Addressed):
    """`enable_schedules`: system/enable_schedule of these schedules; `unknown_schedule_id`,
    and none changed, if one is no schedule."""

    op: Literal['enable_schedules']
    schedule_ids: list[Name] = Field(min_length=1, max_length=IDS_MAX)


class SchedulesRequest(_Addressed):
    """`schedules`: the schedules, every one or those of these ids (those found)."""

    op: Literal['schedules']
    schedule_ids: list[Name] = Field(
        default_factory=list, max_length=IDS_MAX, description='Empty: every schedule.'
    )


class ConfirmRequest(ConfirmTask, _Sourced, _Addressed):
    """`confirm`: answer the waiting system/confirm `task_id`, as the bridge's source followed
    by the name `source` gives, as a start's (its result's `by`: `CLOUD:alice`);
    `unknown_task_id` for a task the node does not know, `not_waiting` for one that is no
    waiting confirmation."""

    op: Literal['confirm']
    task_id: Name = Field(min_length=1, max_length=NAME_MAX)


RequestBody = Annotated[
    StartTaskRequest
    | StartMissionRequest
    | CancelRequest
    | StopRequest
    | HistoryRequest
    | ReprioritizeRequest
    | WhyRequest
    | PauseRequest
    | ResumeRequest
    | ScheduleRequest
    | UnscheduleRequest
    | EnableSchedulesRequest
    | SchedulesRequest
    | ConfirmRequest,
    Field(discriminator='op'),
]


class RobotRequest(RootModel[RequestBody]):
    """A message of `<prefix>/<robot_id>/request`: one operation, named by `op`."""


class Reply(BaseModel):
    """A message of `<prefix>/<robot_id>/reply`: the answer to one request."""

    request_id: str = Field(description="The request's; empty if it could not be read.")
    ok: bool
    op: str = ''
    task_id: str = Field('', description='start_task, start_mission: the task started.')
    subtask_ids: list[str] = Field(default_factory=list, description='Of a mission.')
    duplicate: bool = Field(
        False, description='The task id was known: nothing started, `task` is that task.'
    )
    task: Task | None = Field(
        None,
        description='start: its latest state; cancel, stop, reprioritize, pause, resume, '
        'schedule, unschedule, enable_schedules: the system task, ended.',
    )
    tasks: list[Task] | None = Field(None, description='history: the tasks found.')
    decisions: list[Decision] | None = Field(None, description="why: the task's, oldest first.")
    paused: Paused | None = Field(None, description='pause: the ids paused, why not the others.')
    resumed: Resumed | None = Field(None, description='resume: the ids resumed, why not others.')
    scheduled: Scheduled | None = Field(
        None, description='schedule: whether the Task Manager took it (else why), its first run.'
    )
    schedules: list[Schedule] | None = Field(
        None, description='schedules: those found; enable_schedules: those changed, as now.'
    )
    confirmed: Confirmed | None = Field(None, description='confirm: the answer, taken.')
    error: ErrorDetail | None = Field(None, description='When ok is false.')


ConnectionState = Literal['ONLINE', 'OFFLINE', 'CONNECTIONBROKEN']


class Connection(BaseModel):
    """`<prefix>/<robot_id>/connection` (retained), as VDA 5050's connection topic."""

    robot_id: str
    connection_state: ConnectionState = Field(
        description='ONLINE: the bridge is connected; OFFLINE: it stopped cleanly; '
        'CONNECTIONBROKEN: its last will, sent by the broker when it vanished.'
    )
    timestamp: datetime = Field(
        description='When the state was published (of the last will: when it was set, at '
        'the connection).'
    )
    task_manager_connected: bool = Field(
        False, description='Whether the bridge reaches the Task Manager node.'
    )
    version: str = Field('1', description='Of this protocol.')
    dead_letters: int = Field(
        0,
        description='Request messages the bridge put on `dead_letter` since it started '
        '(in the last will: as many as when it connected).',
    )


class ActiveTasks(BaseModel):
    """`<prefix>/<robot_id>/active_tasks` (retained): every active task, or as many as fit in
    a message (running ones first) and how many were left out."""

    timestamp: datetime
    tasks: list[Task]
    omitted: int = Field(
        0,
        ge=0,
        description="Active tasks left out so that the message fits the broker's size limit "
        '(the running ones come first); each of them is on the `event` topic as it changes.',
    )


class DeclaredTasks(BaseModel):
    """`<prefix>/<robot_id>/tasks` (retained): the tasks the robot runs, or as many as fit in
    a message and how many were left out."""

    timestamp: datetime
    tasks: list[DeclaredTask]
    omitted: int = Field(
        0, ge=0, description="Declared tasks left out so that the message fits the broker's limit."
    )


class DeadLetter(BaseModel):
    """`<prefix>/<robot_id>/dead_letter`: a request message the bridge could not answer, as it
    had no usable request_id to address a reply to (not JSON, not an object, no request_id or
    one of another type), and why. It was acknowledged and nothing ran."""

    robot_id: str
    timestamp: datetime
    error: ErrorDetail = Field(description='Why: the error a reply would have carried.')
    payload_bytes: int = Field(description="The message's size.")
    payload_excerpt: str = Field(
        description='Its first 200 bytes as text (bytes that are not UTF-8 as \\xNN escapes).'
    )
    retained: bool = Field(False, description='Whether it came with the retain flag.')
    count: int = Field(
        description="The robot's dead letters since its bridge started, this one included."
    )
