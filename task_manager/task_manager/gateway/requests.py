"""The gateways' requests as client calls: one function per request document of the protocol,
used by the web gateway and the MQTT bridge alike, so that both ask the Task Manager the same
thing for the same document. They block: call them from a worker thread.

Each door stamps the source of what it starts with its own (`WEB`, `CLOUD`), followed by the
name of who asked (`WEB:alice`, `CLOUD:alice`): `door_source`. No request through a gateway
may claim another door's source (`source_priorities` would rank it as that door's).
"""

from collections.abc import Sequence
from typing import Any

from task_manager.client import (
    ConfirmAnswer,
    Decision,
    ScheduleInfo,
    Subtask,
    TaskHandle,
    TaskManagerClient,
    TaskResult,
    When,
)
from task_manager.core.admission.priority import SOURCE_SEPARATOR
from task_manager.core.sources import SOURCE_NAME, SOURCE_NAME_RULE, door_source
from task_manager.protocol import models

# the fields of a start's options: the same names as the client's keywords
OPTION_FIELDS = frozenset(
    {'priority', 'on_conflict', 'timeout_sec', 'queue_timeout_sec', 'feedback_timeout_sec'}
)


def claimed_source(door: str, claimed: str) -> str:
    """The source of a start through the door `door` whose request says `claimed`: the door's
    own for '' or `door`, `door:name` for a name or `door:name`; ValueError (naming what is
    allowed) for anything else, another door's source among them (`WEB:boss`)."""
    name = claimed.removeprefix(f'{door}{SOURCE_SEPARATOR}') if claimed != door else ''
    if name and not SOURCE_NAME.fullmatch(name):
        raise ValueError(
            f'source: the name of who asks ({SOURCE_NAME_RULE}), or {door}:<name>; the '
            f"source is {door}:<name> (empty: {door}), another door's cannot be claimed"
        )
    return door_source(door, name)


def options_of(
    request: models.StartTask | models.StartMission | models.ScheduleTask,
) -> dict[str, Any]:
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


def pause(client: TaskManagerClient, request: models.PauseTasks, *, source: str) -> TaskResult:
    """system/pause of the request's ids; its result (`successful_pauses`, `errors`)."""
    return client.pause(request.task_ids, source=source)


def resume(client: TaskManagerClient, request: models.ResumeTasks, *, source: str) -> TaskResult:
    """system/resume of the request's ids; its result (`successful_resumes`, `errors`)."""
    return client.resume(request.task_ids, source=source)


def confirm(
    client: TaskManagerClient, task_id: str, request: models.ConfirmTask, *, source: str
) -> ConfirmAnswer:
    """Answer the waiting system/confirm `task_id` as `source` (its result's `by`): taken, or
    why not (`error_code` not_found, not_waiting or invalid_request, and its message)."""
    return client.confirm(task_id, reject=request.reject, comment=request.comment, source=source)


def when_of(request: models.ScheduleTask) -> When:
    """When the request's schedule runs."""
    return When(
        at=request.at,
        delay=request.delay_sec,
        period=request.period_sec,
        cron=request.cron,
        time_zone=request.time_zone,
        window_start=request.window_start,
        window_end=request.window_end,
        max_runs=request.max_runs,
        overlap=request.overlap,
        misfire_grace=request.misfire_grace_sec,
    )


def schedule(client: TaskManagerClient, request: models.ScheduleTask, *, source: str) -> TaskResult:
    """system/schedule of the request's task or mission, each run with the request's options;
    its result (`schedule_id`, `next_run`, `message`)."""
    options = options_of(request)
    # the client's `timeout_sec` is its wait for system/schedule; a run's is task_timeout_sec
    if 'timeout_sec' in options:
        options['task_timeout_sec'] = options.pop('timeout_sec')
    when = when_of(request)
    if request.subtasks is not None:
        subtasks = [
            Subtask(s.task_name, s.task_data, s.allow_skipping, s.task_id) for s in request.subtasks
        ]
        return client.schedule_mission(
            subtasks, when, schedule_id=request.schedule_id, source=source, **options
        )
    return client.schedule_task(
        request.task_name,
        request.task_data,
        when,
        schedule_id=request.schedule_id,
        source=source,
        **options,
    )


class UnknownScheduleError(LookupError):
    """A schedule id the Task Manager has no schedule of."""

    def __init__(self, schedule_id: str, index: int) -> None:
        super().__init__(f'the Task Manager has no schedule {schedule_id!r}')
        self.schedule_id = schedule_id
        self.index = index
        """Its place among the ids asked for."""


def enable_schedules(
    client: TaskManagerClient,
    schedule_ids: Sequence[str],
    request: models.EnableSchedule,
    *,
    source: str,
) -> tuple[TaskResult, list[ScheduleInfo]]:
    """system/enable_schedule of these schedules; its result and the schedules changed, as they
    are then. Every id is looked up first: UnknownScheduleError for the first that is no schedule,
    and nothing is changed."""
    known = {s.schedule_id for s in client.schedules(schedule_ids)}
    for index, schedule_id in enumerate(schedule_ids):
        if schedule_id not in known:
            raise UnknownScheduleError(schedule_id, index)
    result = client.enable_schedules(schedule_ids, request.enabled, source=source)
    changed = list(dict.fromkeys(result.result.get('changed', [])))
    return result, client.schedules(changed) if changed else []


def enable_schedule(
    client: TaskManagerClient, schedule_id: str, request: models.EnableSchedule, *, source: str
) -> ScheduleInfo | None:
    """system/enable_schedule of one schedule; the schedule then, None when there is none."""
    try:
        _, found = enable_schedules(client, [schedule_id], request, source=source)
    except UnknownScheduleError:
        return None
    return found[0] if found else None


def unschedule(client: TaskManagerClient, schedule_id: str, *, source: str) -> TaskResult | None:
    """system/unschedule of one schedule; its result, None when there is no such schedule (it
    is looked up first: then nothing runs)."""
    if not client.schedules([schedule_id]):
        return None
    result = client.unschedule([schedule_id], source=source)
    return result if schedule_id in result.result.get('removed', []) else None
