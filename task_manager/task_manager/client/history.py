"""What the Task Manager keeps of tasks: their current states, its recent results, and its
durable history, read page by page, with the statistics made from it."""

from collections.abc import Sequence
from datetime import UTC, datetime, timedelta

from task_manager_msgs.srv import GetTaskResults, GetTaskStates, QueryTaskHistory

from task_manager.client.records import Decision, TaskResult, TaskState
from task_manager.client.services import CallService
from task_manager.core.errors import TaskManagerError
from task_manager.core.history.stats import TaskStats, task_stats
from task_manager.core.names import (
    GET_TASK_RESULTS_SERVICE,
    GET_TASK_STATES_SERVICE,
    HISTORY_QUERY_LIMIT_MAX,
    QUERY_TASK_HISTORY_SERVICE,
)
from task_manager.core.status import TaskStatus
from task_manager.messages.task_messages import stamp

FINAL_STATUSES = tuple(s.value for s in TaskStatus if s.is_final)


class History:
    """The Task Manager's query services, through `call`."""

    def __init__(self, call: CallService) -> None:
        self._call = call

    def task_states(self, task_ids: Sequence[str], timeout_sec: float | None) -> list[TaskState]:
        request = GetTaskStates.Request(task_ids=list(task_ids))
        response = self._call(GetTaskStates, GET_TASK_STATES_SERVICE, request, timeout_sec)
        return [TaskState.from_message(m) for m in response.tasks]

    def why(self, task_id: str, timeout_sec: float | None) -> list[Decision]:
        """See TaskManagerClient.why."""
        states = self.task_states([task_id], timeout_sec)
        if not states:
            raise TaskManagerError(
                f'the Task Manager knows no task {task_id!r} (neither active nor in its history)'
            )
        return states[0].decisions

    def recent_results(self, max_results: int) -> list[TaskResult]:
        request = GetTaskResults.Request(max_results=max_results)
        response = self._call(GetTaskResults, GET_TASK_RESULTS_SERVICE, request)
        results = [TaskResult.from_message(m) for m in response.results]
        if not results:
            return results
        # key: task id, value: its kept state (the latest task of that id)
        ids = sorted({r.task_id for r in results})
        states = {s.task_id: s for s in self.task_states(ids, None)}
        # key: task id, value: the index of its newest result, the one that state is of (an id
        # may be used again once its task ended: the older results keep no stamps)
        newest = {result.task_id: index for index, result in enumerate(results)}
        return [
            result.with_stamps_of(state)
            if newest[result.task_id] == index
            and (state := states.get(result.task_id)) is not None
            and state.is_final
            else result
            for index, result in enumerate(results)
        ]

    def history(
        self,
        task_name: str = '',
        *,
        status: TaskStatus | str = '',
        source: str = '',
        mission_id: str = '',
        since: datetime | timedelta | None = None,
        until: datetime | None = None,
        after_sequence: int = 0,
        limit: int = 100,
        oldest_first: bool = False,
        timeout_sec: float | None = None,
    ) -> list[TaskState]:
        if not 1 <= limit <= HISTORY_QUERY_LIMIT_MAX:
            raise ValueError(f'limit must be from 1 to {HISTORY_QUERY_LIMIT_MAX}, got {limit}')
        if status and status not in FINAL_STATUSES:
            allowed = ', '.join(FINAL_STATUSES)
            raise ValueError(f'status must be one of {allowed} (or empty), got {status!r}')
        if isinstance(since, timedelta):
            since = datetime.now(UTC) - since
        request = QueryTaskHistory.Request(
            task_name=task_name,
            status=str(status),
            source=source,
            mission_id=mission_id,
            ended_after=stamp(None if since is None else since.timestamp()),
            ended_before=stamp(None if until is None else until.timestamp()),
            after_sequence=after_sequence,
            limit=limit,
            oldest_first=oldest_first,
        )
        response = self._call(QueryTaskHistory, QUERY_TASK_HISTORY_SERVICE, request, timeout_sec)
        return [TaskState.from_message(m) for m in response.tasks]

    def stats(
        self,
        task_name: str,
        *,
        source: str,
        mission_id: str,
        since: datetime | timedelta,
        until: datetime | None,
        timeout_sec: float | None,
    ) -> list[TaskStats]:
        if isinstance(since, timedelta):
            since = datetime.now(UTC) - since  # one range for every page
        ended: list[TaskState] = []
        while True:
            page = self.history(
                task_name,
                source=source,
                mission_id=mission_id,
                since=since,
                until=until,
                after_sequence=ended[-1].sequence if ended else 0,
                limit=HISTORY_QUERY_LIMIT_MAX,
                oldest_first=True,
                timeout_sec=timeout_sec,
            )
            ended.extend(page)
            if len(page) < HISTORY_QUERY_LIMIT_MAX:
                return task_stats(ended)
