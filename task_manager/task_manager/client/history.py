"""What the Task Manager keeps and declares: the current states of tasks, its recent results,
its durable history (read page by page, with the statistics made from it) and the declared
tasks (read from its parameters)."""

from collections.abc import Iterator, Sequence
from datetime import UTC, datetime, timedelta
from typing import Any

from rcl_interfaces.srv import GetParameters, ListParameters
from rclpy.parameter import parameter_value_to_python
from task_manager_msgs.srv import GetTaskResults, GetTaskStates, QueryTaskHistory

from task_manager.client.records import Decision, TaskResult, TaskState
from task_manager.client.services import ClientParts, id_asks
from task_manager.core.errors import TaskManagerError
from task_manager.core.history.stats import TaskStats, task_stats
from task_manager.core.names import (
    GET_PARAMETERS_SERVICE,
    GET_TASK_RESULTS_SERVICE,
    GET_TASK_STATES_SERVICE,
    HISTORY_QUERY_LIMIT_MAX,
    LIST_PARAMETERS_SERVICE,
    QUERY_TASK_HISTORY_SERVICE,
)
from task_manager.core.status import TaskStatus
from task_manager.core.system_tasks import SYSTEM_SPECS
from task_manager.messages.task_messages import stamp

FINAL_STATUSES = tuple(s.value for s in TaskStatus if s.is_final)


class HistoryQueries(ClientParts):
    """TaskManagerClient's reads of what the Task Manager keeps, through its query services."""

    def task_states(
        self, task_ids: Sequence[str] = (), timeout_sec: float | None = None
    ) -> list[TaskState]:
        """The current state of these tasks (active or ended and kept), or of every active one.

        Ids the Task Manager does not know are left out. More than IDS_MAX ids (what it answers
        in one request) are asked in several.
        """
        states = []
        for ids in id_asks(task_ids):  # no ids: one request, for every active task
            request = GetTaskStates.Request(task_ids=ids)
            response = self._call(GetTaskStates, GET_TASK_STATES_SERVICE, request, timeout_sec)
            states += [TaskState.from_message(m) for m in response.tasks]
        return states

    def why(self, task_id: str, timeout_sec: float | None = None) -> list[Decision]:
        """Every decision the Task Manager took about a task, oldest first: queued, started
        (after a wait, or pre-empting), refused, pre-empted, timed out, retried,
        reprioritized, each with its reason; empty when it was simply started.

        From its state while it is active, else from the history; TaskManagerError when the
        Task Manager knows no such task.
        """
        states = self.task_states([task_id], timeout_sec)
        if not states:
            raise TaskManagerError(
                f'the Task Manager knows no task {task_id!r} (neither active nor in its history)'
            )
        return states[0].decisions

    def recent_results(self, max_results: int = 0) -> list[TaskResult]:
        """Results the Task Manager has kept (oldest first), including from before we started.

        With their stamps, from /task_manager/get_task_states.
        """
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
        """Ended tasks from the Task Manager's durable history, newest first.

        Empty filters do not filter. `since`: ended at or after this moment, or within this
        long before now; `until`: ended at or before it. `after_sequence`: only tasks whose
        `sequence` is greater; with `oldest_first` the tasks come by sequence, so that a
        consumer can resume after the last one it saw. At most `limit` (1 to 10,000).
        """
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
        task_name: str = '',
        *,
        source: str = '',
        mission_id: str = '',
        since: datetime | timedelta = timedelta(days=1),
        until: datetime | None = None,
        timeout_sec: float | None = None,
    ) -> list[TaskStats]:
        """Per task name: count, success rate, median and p95 duration of the tasks that ended
        in the range (default: the last 24 h), computed here from the whole history range.

        The history is read by sequence, 10,000 tasks per call (each call bounded by the
        timeout).
        """
        ended = self.ended_after(
            task_name=task_name,
            source=source,
            mission_id=mission_id,
            since=since,
            until=until,
            page=HISTORY_QUERY_LIMIT_MAX,
            timeout_sec=timeout_sec,
        )
        return task_stats(list(ended))

    def ended_after(
        self,
        after_sequence: int = 0,
        *,
        task_name: str = '',
        source: str = '',
        mission_id: str = '',
        since: datetime | timedelta | None = None,
        until: datetime | None = None,
        page: int = 1000,
        timeout_sec: float | None = None,
    ) -> Iterator[TaskState]:
        """Every ended task of the history after `after_sequence` (the filters as `history`'s),
        oldest first, read a page of `page` at a time as the caller takes them (each read
        bounded by the timeout): a consumer resumes after the last one it took."""
        if isinstance(since, timedelta):
            since = datetime.now(UTC) - since  # one range for every page
        while True:
            found = self.history(
                task_name,
                source=source,
                mission_id=mission_id,
                since=since,
                until=until,
                after_sequence=after_sequence,
                limit=page,
                oldest_first=True,
                timeout_sec=timeout_sec,
            )
            yield from found
            if len(found) < page:
                return
            after_sequence = found[-1].sequence

    def declared_tasks(self) -> list[dict[str, Any]]:
        """The declared tasks and their properties, read from the node's parameters, then the
        system tasks.

        Through the client's own two clients of the node's parameter services (made once): a
        parameter client per call (rclpy's AsyncParameterClient makes six) was never
        destroyed, and every process of the domain grew with each read.
        """
        listed = self._call(ListParameters, LIST_PARAMETERS_SERVICE, ListParameters.Request())
        names = list(listed.result.names)
        request = GetParameters.Request(names=names)
        got = self._call(GetParameters, GET_PARAMETERS_SERVICE, request)
        values = {n: parameter_value_to_python(v) for n, v in zip(names, got.values, strict=True)}
        return [*_declared_in(values), *_system_tasks()]


def _declared_in(values: dict[str, Any]) -> list[dict[str, Any]]:
    return [
        {
            'key': key,
            **{n[len(key) + 1 :]: v for n, v in values.items() if n.startswith(f'{key}.')},
        }
        for key in values.get('tasks') or []
    ]


def _system_tasks() -> list[dict[str, Any]]:
    return [
        {
            'key': '',
            'task_name': spec.task_name,
            'msg_interface': str(spec.interface),
            'topic': '',
            'blocking': spec.blocking,
            'cancel_on_stop': spec.cancel_on_stop,
            'reentrant': spec.reentrant,
            'cancel_reported_as_success': spec.cancel_reported_as_success,
            'cancel_timeout': spec.cancel_timeout_sec,
            'pause': spec.pause.value,
        }
        for spec in SYSTEM_SPECS
    ]
