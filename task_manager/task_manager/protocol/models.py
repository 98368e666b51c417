"""The JSON documents non-ROS sources send and receive, as pydantic models.

Requests forbid unknown keys, so that a misspelt field is an error naming it rather than a
default silently taken. Stamps are ISO 8601 in UTC; statuses and error codes are the strings
of the ROS interfaces.
"""

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    AwareDatetime,
    BaseModel,
    ConfigDict,
    Field,
    StrictBool,
    StrictFloat,
    StrictInt,
    model_validator,
)

from task_manager.core.bounds import DECISIONS_PER_TASK_MAX, PRIORITY
from task_manager.core.confirmation import TEXT_MAX_LENGTH
from task_manager.core.names import HISTORY_QUERY_LIMIT_MAX, IDS_MAX
from task_manager.core.text.request_text import MAX_LENGTH, is_refused_character

NAME_MAX = MAX_LENGTH
"""The longest task name, task id or source accepted."""

TaskStatusName = Literal[
    'RECEIVED', 'QUEUED', 'IN_PROGRESS', 'PAUSED', 'DONE', 'ERROR', 'CANCELED'
]  # fmt: skip
ErrorCodeName = Literal[
    '', 'duplicate_id', 'task_data_parsing_failed', 'task_start_failed', 'task_cancel_failed',
    'unknown_task', 'invalid_request', 'preemption_refused', 'resource_busy', 'queue_full',
    'timeout', 'rejected',
]  # fmt: skip


def _without_refused_characters(text: str) -> str:
    """Refuse what ROS would cut (NUL) or a log line or a screen would misread."""
    if any(is_refused_character(character) for character in text):
        raise ValueError(
            'control characters and characters that reorder text (right-to-left overrides) '
            'are not allowed'
        )
    return text


Name = Annotated[str, AfterValidator(_without_refused_characters)]
"""A task id, task name or source of a request."""
PauseModeName = Literal['none', 'restart', 'between_subtasks']
EventName = Literal[
    'RECEIVED', 'QUEUED', 'STARTED', 'FEEDBACK', 'PAUSED', 'RESUMED', 'DECIDED', 'ENDED'
]  # fmt: skip


class _Request(BaseModel):
    model_config = ConfigDict(extra='forbid')


Priority = Annotated[StrictInt, Field(ge=PRIORITY.low, le=PRIORITY.high)]
Seconds = Annotated[StrictFloat, Field(gt=0, allow_inf_nan=False)]
OnConflictName = Literal['preempt', 'queue', 'reject']


class _Options(_Request):
    """How a start is admitted and bounded; each left out takes the task's declaration."""

    priority: Priority | None = Field(
        None, description='Higher wins; it pre-empts only tasks of at most its priority.'
    )
    on_conflict: OnConflictName | None = Field(
        None, description='When its resources are busy: pre-empt their holders, wait, or fail.'
    )
    timeout_sec: Seconds | None = Field(
        None, description='From start to end; then it is cancelled, ERROR / timeout.'
    )
    queue_timeout_sec: Seconds | None = Field(
        None, description='The longest wait in the queue; then ERROR / timeout, never started.'
    )
    feedback_timeout_sec: Seconds | None = Field(
        None, description='An action without feedback this long is stalled: ERROR / timeout.'
    )


class StartTask(_Options):
    """Start one task. Its source is not the request's to say: the web gateway sets it (`WEB`),
    so that the history says who started it."""

    task_name: Name = Field(min_length=1, max_length=NAME_MAX, examples=['navigation/navigate'])
    task_data: dict[str, Any] = Field(
        default_factory=dict, description="The goal's fields (see the task's goal_schema)."
    )
    task_id: Name = Field('', max_length=NAME_MAX, description='Empty: one is generated.')


class Subtask(_Request):
    """One step of a mission."""

    task_name: Name = Field(min_length=1, max_length=NAME_MAX)
    task_data: dict[str, Any] = Field(default_factory=dict)
    task_id: Name = Field('', max_length=NAME_MAX, description='Empty: one is generated.')
    allow_skipping: bool = Field(False, description='Its failure does not end the mission.')


class StartMission(_Options):
    """Start system/mission: its subtasks one after another (source: as StartTask). The
    options are the mission's, as one unit (it queues as one)."""

    subtasks: list[Subtask] = Field(min_length=1, max_length=IDS_MAX)
    task_id: Name = Field('', max_length=NAME_MAX, description='Empty: one is generated.')


class CancelTasks(_Request):
    """Cancel tasks by id, whoever started them."""

    task_ids: list[Name] = Field(min_length=1, max_length=IDS_MAX)


class Reprioritize(_Request):
    """system/reprioritize: a new priority for active tasks (a queued one moves at once)."""

    task_ids: list[Name] = Field(min_length=1, max_length=IDS_MAX)
    priority: Priority


class PauseTasks(_Request):
    """system/pause: pause active tasks by id (a mission between its subtasks, a task declared
    `pause: restart` at once)."""

    task_ids: list[Name] = Field(min_length=1, max_length=IDS_MAX)


class ResumeTasks(_Request):
    """system/resume: paused tasks run again."""

    task_ids: list[Name] = Field(min_length=1, max_length=IDS_MAX)


class ConfirmTask(_Request):
    """Answer a waiting system/confirm: confirm it (it ends DONE) or reject it (ERROR,
    `rejected`). Who answers is not the request's to say: the gateway names its caller
    (`WEB:alice`), and the task's result keeps it as `by`."""

    reject: StrictBool = Field(False, description='True: reject; false: confirm.')
    comment: Name = Field(
        '', max_length=TEXT_MAX_LENGTH, description='Why, kept in the result (optional).'
    )


class Confirmed(BaseModel):
    """The answer to a ConfirmTask the Task Manager took: the task ends with it."""

    task_id: str
    outcome: Literal['confirmed', 'rejected']
    by: str = Field(description="Who answered, as the task's result says.", examples=['WEB:alice'])
    comment: str = ''


OverlapName = Literal['', 'SKIP', 'BUFFER_ONE', 'CANCEL_OTHER', 'ALLOW_ALL']
WHEN_FIELDS = ('at', 'delay_sec', 'period_sec', 'cron')
"""A schedule gives exactly one of them."""


class ScheduleTask(_Options):
    """system/schedule: a task (task_name) or a mission (subtasks) the Task Manager starts at
    set times, with the options of a start for each run (source: as StartTask).

    Exactly one of `at` (once), `delay_sec` (once, this long from now), `period_sec` (every
    period, from window_start or one period from now), `cron` (5 fields, in time_zone).
    """

    schedule_id: Name = Field('', max_length=NAME_MAX, description='Empty: one is generated.')
    task_name: Name = Field('', max_length=NAME_MAX, description='A task; or give subtasks.')
    task_data: dict[str, Any] = Field(default_factory=dict)
    subtasks: list[Subtask] | None = Field(
        None,
        min_length=1,
        max_length=IDS_MAX,
        description='A mission (system/mission); subtask ids only in a schedule that runs once.',
    )
    at: AwareDatetime | None = Field(None, description='Once, at this time (with its zone).')
    delay_sec: Seconds | None = Field(None, description='Once, this long from now.')
    period_sec: Seconds | None = Field(None, description='Every period.')
    cron: Name = Field('', max_length=NAME_MAX, examples=['0 2 * * *'])
    time_zone: Name = Field('', max_length=NAME_MAX, description="Of cron, an IANA name; '': UTC.")
    window_start: AwareDatetime | None = Field(None, description='No run before.')
    window_end: AwareDatetime | None = Field(None, description='No run after.')
    max_runs: StrictInt = Field(0, ge=0, description='0: no limit.')
    overlap: OverlapName = Field(
        '', description="A run due while the previous is active: '' is SKIP."
    )
    misfire_grace_sec: Annotated[StrictFloat, Field(ge=0, allow_inf_nan=False)] | None = Field(
        None, description='How late a run missed while the Task Manager was down may run.'
    )

    @model_validator(mode='after')
    def _one_what_and_one_when(self) -> 'ScheduleTask':
        if bool(self.task_name) == (self.subtasks is not None):
            raise ValueError('give either task_name (a task) or subtasks (a mission)')
        given = [name for name in WHEN_FIELDS if getattr(self, name) not in (None, '')]
        if len(given) != 1:
            got = ' and '.join(given) if given else 'none'
            raise ValueError(f'give exactly one of at, delay_sec, period_sec, cron; got {got}')
        runs_once = self.at is not None or self.delay_sec is not None or self.max_runs == 1
        fixed = [s.task_id for s in self.subtasks or [] if s.task_id]
        if fixed and not runs_once:
            raise ValueError(
                f'subtask ids {", ".join(fixed)} would repeat in every run; leave task_id '
                'empty in a repeating schedule (each run makes its own)'
            )
        return self


class EnableSchedule(_Request):
    """Disable a schedule (no runs; its state and counts kept) or enable it again (from the
    next due time after now)."""

    enabled: StrictBool


class HistoryQuery(_Request):
    """Which ended tasks to read from the durable history; empty filters do not filter."""

    task_name: str = ''
    status: Literal['', 'DONE', 'ERROR', 'CANCELED'] = Field('', description='Empty: any.')
    source: str = ''
    mission_id: str = ''
    since: datetime | None = Field(None, description='Ended at or after this moment.')
    until: datetime | None = Field(None, description='Ended at or before this moment.')
    after_sequence: int = Field(0, ge=0, description='Only tasks with a greater sequence.')
    limit: int = Field(100, ge=1, le=HISTORY_QUERY_LIMIT_MAX)
    oldest_first: bool = Field(False, description='By sequence, to resume after the last seen.')


class Decision(BaseModel):
    """One decision the Task Manager took about a task, and why."""

    at: datetime
    decision: str = Field(
        examples=['queued', 'started', 'refused', 'preempted', 'timeout', 'retry',
                  'reprioritized', 'omitted'],
        description='`omitted`: no decision, but where decisions were left out (a task keeps '
        f'at most {DECISIONS_PER_TASK_MAX}: its first and its newest).',
    )  # fmt: skip
    reason: str = Field(examples=['queued behind drive-1 (priority 5), which holds base'])
    omitted: int = Field(0, ge=0, description='Of an `omitted` entry: how many were left out.')


class Task(BaseModel):
    """Everything known of one task: while it runs, and once it ended (with its result)."""

    task_id: str
    task_name: str
    source: str
    status: TaskStatusName
    error_code: ErrorCodeName = ''
    error_message: str = Field('', description='Why the Task Manager refused or failed it.')
    mission_id: str = Field('', description='The mission it is a subtask of; empty if none.')
    received: datetime | None = None
    started: datetime | None = Field(None, description='None while (or if never) started.')
    ended: datetime | None = None
    duration_sec: float | None = Field(
        None, description='Running time: from its start to its end, less paused_sec.'
    )
    paused_sec: float = Field(0, description='Time spent PAUSED (by system/pause).')
    feedback: dict[str, Any] | None = Field(None, description='The latest feedback.')
    result: dict[str, Any] | None = Field(None, description='Once ended.')
    sequence: int = Field(0, description='Once ended: its number in the history; else 0.')
    priority: int = Field(0, description='The priority it was admitted with (higher wins).')
    queue_position: int = Field(0, description='While QUEUED: its place, 1 first; else 0.')
    attempt: int = Field(1, description='Which attempt, 1 first (more once retried).')
    decisions: list[Decision] = Field(
        default_factory=list, description='Why it was queued, refused, pre-empted, ...'
    )


class TaskEvent(BaseModel):
    """One change of one task."""

    event: EventName
    stamp: datetime
    task: Task
    reason: str = Field('', description='Why, when the Task Manager decided it; else empty.')


class Started(BaseModel):
    """The answer to a start: the task id at once, the task once it ended."""

    task_id: str
    subtask_ids: list[str] = Field(default_factory=list, description='Of a mission.')
    ended: bool = Field(description='Whether `task` is the final state (with the result).')
    task: Task | None = Field(None, description='The latest state known, if any.')


class _PauseAnswer(BaseModel):
    errors: list[str] = Field(
        default_factory=list, description='Why not, one line per other id (e.g. not active).'
    )
    task: Task = Field(description='The system task, ended (DONE when every id was done).')


class Paused(_PauseAnswer):
    """The answer to a pause: the ids paused (one already paused counts) and why not the
    others."""

    paused: list[str]


class Resumed(_PauseAnswer):
    """The answer to a resume: the ids running again and why not the others."""

    resumed: list[str]


class Scheduled(BaseModel):
    """The answer to a schedule: whether the Task Manager took it, and its first run."""

    scheduled: bool
    schedule_id: str
    next_run: datetime | None = Field(None, description='None: no run to come.')
    message: str = Field(description='When it runs, in words; or why it was refused.')
    task: Task = Field(description='The system/schedule task, ended.')


class Schedule(BaseModel):
    """One schedule of the Task Manager (/task_manager/get_schedules)."""

    schedule_id: str
    task_name: str = Field(description='What each run starts (system/mission: a mission).')
    task_data: dict[str, Any]
    options: dict[str, Any] = Field(description="Each run's; empty: the declaration's.")
    created_by: str = Field(description='The source that made it.')
    description: str = Field(examples=['every 7200 s', "cron '0 2 * * *' (Europe/Paris)"])
    at: datetime | None = None
    period_sec: float | None = None
    cron: str = ''
    time_zone: str = ''
    window_start: datetime | None = None
    window_end: datetime | None = None
    max_runs: int = Field(0, description='0: no limit.')
    overlap: OverlapName
    misfire_grace_sec: float
    enabled: bool
    created: datetime | None = None
    next_run: datetime | None = Field(None, description='None: no run to come.')
    last_run: datetime | None = Field(None, description='None before the first.')
    last_task_id: str = ''
    last_status: TaskStatusName | None = Field(None, description='Of the last run, if any.')
    run_count: int
    missed_count: int = Field(description='Due times not run (the Task Manager was down, ...).')
    skipped_count: int = Field(description='Due times skipped by the overlap policy.')


class ErrorDetail(BaseModel):
    code: str = Field(examples=['invalid_request', 'unauthorized', 'task_manager_unavailable'])
    message: str
    field: str = Field('', description='The field at fault, dotted, when one is.')


class Error(BaseModel):
    """Every error answer: a code to branch on and a message that says what is allowed."""

    error: ErrorDetail


class DeclaredTask(BaseModel):
    """A task the Task Manager runs, with its properties and the schema of its task_data."""

    task_name: str
    msg_interface: str
    topic: str = ''
    blocking: bool = False
    cancel_on_stop: bool = False
    reentrant: bool = False
    cancel_reported_as_success: bool = False
    resources: list[str] = Field(
        default_factory=list,
        description='The resources it holds while it runs, as declared (none: left out); a '
        'blocking task also holds the blocking slot, one not reentrant its one goal slot.',
    )
    pause: PauseModeName = Field(
        'none',
        description='How it pauses: none (it cannot), restart (its goal is cancelled and sent '
        'again on resume), between_subtasks (system/mission).',
    )
    goal_schema: dict[str, Any] = Field(
        default_factory=dict, description='JSON Schema of task_data, from its ROS interface.'
    )
