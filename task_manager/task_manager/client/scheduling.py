"""TaskManagerClient's schedules: tasks and missions the Task Manager starts at set times,
made, removed and switched through system/schedule, system/unschedule and
system/enable_schedule, and listed through /task_manager/get_schedules (the values they
take and give are in schedules.py)."""

from collections.abc import Sequence
from typing import Any, Unpack, cast

from task_manager_msgs.srv import GetSchedules

from task_manager.client.missions import Subtask, mission_task_data
from task_manager.client.records import TaskResult
from task_manager.client.schedules import (
    ScheduleInfo,
    When,
    WhenKeywords,
    schedule_request,
    when_of,
)
from task_manager.client.services import ClientParts, id_asks
from task_manager.client.tasks import request_options
from task_manager.core.admission.options import OnConflict, RequestOptions
from task_manager.core.names import ENABLE_SCHEDULE as ENABLE_SCHEDULE_TASK
from task_manager.core.names import GET_SCHEDULES_SERVICE, MISSION
from task_manager.core.names import SCHEDULE as SCHEDULE_TASK
from task_manager.core.names import UNSCHEDULE as UNSCHEDULE_TASK


class ScheduleKeywords(WhenKeywords, total=False):
    """What schedule_task and schedule_mission take as keywords besides the schedule's id,
    source and wait: the fields of When (`period=3600`), and the options each run is started
    with (None: the task's declaration), the run's own timeout being `task_timeout_sec`."""

    priority: int | None
    on_conflict: OnConflict | str | None
    task_timeout_sec: float | None
    queue_timeout_sec: float | None
    feedback_timeout_sec: float | None


def _when_and_options(when: When | None, keywords: ScheduleKeywords) -> tuple[When, RequestOptions]:
    """When the schedule runs, and its runs' options; ValueError says what is wrong, TypeError
    names a keyword that is neither (as Python does for a keyword no signature has)."""
    unknown = sorted(set(keywords) - ScheduleKeywords.__optional_keys__)
    if unknown:
        raise TypeError(f'unexpected keyword argument(s): {", ".join(unknown)}')
    fields = {n: v for n, v in keywords.items() if n in WhenKeywords.__optional_keys__}
    runs_when = when_of(when, cast(WhenKeywords, fields))
    options = request_options(
        keywords.get('priority'),
        keywords.get('on_conflict'),
        keywords.get('task_timeout_sec'),
        keywords.get('queue_timeout_sec'),
        keywords.get('feedback_timeout_sec'),
    )
    return runs_when, options


class Scheduling(ClientParts):
    """Makes, removes, switches and lists schedules."""

    def schedule_task(
        self,
        task_name: str,
        task_data: dict[str, Any] | str | None = None,
        when: When | None = None,
        *,
        schedule_id: str = '',
        source: str = 'python',
        timeout_sec: float | None = None,
        **keywords: Unpack[ScheduleKeywords],
    ) -> TaskResult:
        """Schedule a task through system/schedule; its result has `schedule_id` and
        `next_run` (see scheduled_next_run), or `message` saying why it was refused.

        `when` (a When), or its fields as keywords (`period=3600`, `cron='0 2 * * *'`, ...),
        says when it runs; ValueError says what is wrong before sending. `timeout_sec` is
        the longest wait for system/schedule's result. Each run is started with start_task's
        options as keywords (`priority`, `on_conflict`, `queue_timeout_sec`,
        `feedback_timeout_sec`; None: the task's declaration), the run's own timeout being
        `task_timeout_sec` here, as in run_task.
        """
        runs_when, options = _when_and_options(when, keywords)
        data = schedule_request(
            task_name, task_data, runs_when, schedule_id=schedule_id, options=options
        )
        return self._system_task(SCHEDULE_TASK, data, source=source, timeout_sec=timeout_sec)

    def schedule_mission(
        self,
        subtasks: Sequence[Subtask],
        when: When | None = None,
        *,
        schedule_id: str = '',
        source: str = 'python',
        timeout_sec: float | None = None,
        **keywords: Unpack[ScheduleKeywords],
    ) -> TaskResult:
        """Schedule system/mission with these subtasks, as schedule_task does.

        Each run makes its own subtask ids; a subtask id given is refused for a schedule that
        may run more than once, since two runs cannot share task ids. The options are
        schedule_task's, for each run's mission as one unit (as start_mission's).
        """
        runs_when, _ = _when_and_options(when, keywords)
        fixed = [s.task_id for s in subtasks if s.task_id]
        if fixed and not runs_when.runs_once:
            raise ValueError(
                f'subtask ids {", ".join(fixed)} would repeat in every run; leave task_id '
                'empty in a repeating schedule (each run makes its own)'
            )
        mission = mission_task_data(subtasks, [s.task_id for s in subtasks])
        return self.schedule_task(
            MISSION,
            mission,
            when,
            schedule_id=schedule_id,
            source=source,
            timeout_sec=timeout_sec,
            **keywords,
        )

    def unschedule(
        self,
        schedule_ids: Sequence[str],
        *,
        source: str = 'python',
        timeout_sec: float | None = None,
    ) -> TaskResult:
        """Remove schedules through system/unschedule (their runs already started go on).

        Its result has `removed` and `errors` (one line per id that is not a schedule).
        """
        data = {'schedule_ids': list(schedule_ids)}
        return self._system_task(UNSCHEDULE_TASK, data, source=source, timeout_sec=timeout_sec)

    def enable_schedules(
        self,
        schedule_ids: Sequence[str],
        enabled: bool,
        *,
        source: str = 'python',
        timeout_sec: float | None = None,
    ) -> TaskResult:
        """Disable schedules (no runs; state and counts kept) or enable them again (from the
        next due time after now) through system/enable_schedule.

        Its result has `changed` and `errors` (one line per id that is not a schedule).
        """
        data = {'schedule_ids': list(schedule_ids), 'enabled': enabled}
        return self._system_task(ENABLE_SCHEDULE_TASK, data, source=source, timeout_sec=timeout_sec)

    def schedules(
        self, schedule_ids: Sequence[str] | None = None, timeout_sec: float | None = None
    ) -> list[ScheduleInfo]:
        """These schedules (ids that are not schedules are left out), or every one (None).
        More than IDS_MAX ids (what the Task Manager answers in one request) are asked in
        several."""
        schedules = []
        for some_ids in id_asks(schedule_ids or []):
            request = GetSchedules.Request(schedule_ids=some_ids)
            response = self._call(GetSchedules, GET_SCHEDULES_SERVICE, request, timeout_sec)
            schedules += [ScheduleInfo.from_message(m) for m in response.schedules]
        return schedules
