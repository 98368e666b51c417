"""`TaskManagerClient`: start, watch, cancel, pause and schedule tasks of a running Task Manager.

The client generates every task id itself and takes a task's outcome from whichever comes
first, the ExecuteTask result or the task's message on /task_manager/results, so a lost
reply on the network never leaves a script waiting: every wait is bounded.

Stamps and feedback come from /task_manager/task_events, which a client subscribes to once,
on first use (starting a task, asking for feedback or events); each event goes to the
handle of its task by id. A client that joins late asks /task_manager/get_task_states.

A request may carry options (priority, on_conflict, timeouts; None: the task's declaration):
with any, it goes to /task_manager/start_task, else to ExecuteTask as it always did.

The client holds one helper per concern and hands each what it needs: the connection, the
tasks it started, the watchers of what the node publishes, the query services, the pauses
and schedules (which start system tasks through `run_task`) and the answers to confirmations.
"""

from collections.abc import Callable, Iterator, Sequence
from datetime import datetime, timedelta
from typing import Any, Unpack

from rclpy.task import Future

from task_manager.client.connection import DEFAULT_TIMEOUT_SEC, Connection
from task_manager.client.handle import TaskHandle
from task_manager.client.history import History
from task_manager.client.interventions import ConfirmAnswer, Confirmations, Pauses
from task_manager.client.listeners import Callback
from task_manager.client.missions import Subtask
from task_manager.client.parameters import declared_tasks
from task_manager.client.records import (
    ActiveTaskInfo,
    Decision,
    TaskEvent,
    TaskResult,
    TaskState,
)
from task_manager.client.schedules import ScheduleInfo, Schedules, When, WhenKeywords, when_of
from task_manager.client.services import ServiceCalls
from task_manager.client.tasks import Tasks, check_priority, request_options
from task_manager.client.watching import ActiveTasks, Watch
from task_manager.core.admission.options import OnConflict
from task_manager.core.history.stats import TaskStats
from task_manager.core.names import CANCEL_TASK, REPRIORITIZE, STOP
from task_manager.core.status import TaskStatus


class TaskManagerClient:
    """A client of the Task Manager with its own node, spun in a background thread.

    Use it as a context manager, or call `close()`.
    """

    def __init__(
        self, node_name: str = 'task_manager_client', timeout_sec: float = DEFAULT_TIMEOUT_SEC
    ) -> None:
        self._connection = Connection(node_name, timeout_sec)
        self.node = self._connection.node
        self._active = ActiveTasks(self._connection)
        self._tasks = Tasks(self._connection, self._active)
        self._watch = Watch(self._connection, self._active, self._tasks.results, self._tasks.events)
        self._services = ServiceCalls(self._connection)
        self._history = History(self._services.call)
        self._pauses = Pauses(self.run_task)
        self._schedules = Schedules(self.run_task, self._services.call)
        self._confirmations = Confirmations(self._services.call)
        self._connection.start()

    @property
    def timeout_sec(self) -> float:
        """How long a call waits when not told."""
        return self._connection.timeout_sec

    @timeout_sec.setter
    def timeout_sec(self, timeout_sec: float) -> None:
        self._connection.timeout_sec = timeout_sec

    # ---- lifecycle and connection ------------------------------------------------------------

    def __enter__(self) -> 'TaskManagerClient':
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def close(self) -> None:
        self._connection.close()

    def wait_until_available(
        self, timeout_sec: float | None = None, *, events: bool = False
    ) -> None:
        """Wait for the Task Manager's action server and topics; TaskManagerUnavailable if not.

        With `events`, also subscribe to /task_manager/task_events now and wait until it is
        connected, if the Task Manager publishes it (see `events_connected`).
        """
        self._tasks.wait_until_available(timeout_sec, events=events)

    @property
    def connected(self) -> bool:
        """Whether a Task Manager is there: its /task_manager/active_tasks reaches this client.

        It turns False at once when the node stops, and after DDS's lease duration when the
        node's process dies without stopping.
        """
        return self._connection.connected

    @property
    def events_connected(self) -> bool:
        """Whether /task_manager/task_events reaches this client (it can be switched off)."""
        return self._tasks.events.connected

    def on_connection_change(self, callback: Callable[[bool], None]) -> Callable[[], None]:
        """Call `callback(connected)` each time `connected` changes; returns the unsubscribe.

        Like every callback of the client, it runs on the executor thread and must be quick.
        """
        return self._connection.changes.add(Callback(callback, self.node.get_logger()))

    # ---- starting tasks ----------------------------------------------------------------------

    def start_task(
        self,
        task_name: str,
        task_data: dict[str, Any] | str | None = None,
        *,
        task_id: str = '',
        source: str = 'python',
        priority: int | None = None,
        on_conflict: OnConflict | str | None = None,
        timeout_sec: float | None = None,
        queue_timeout_sec: float | None = None,
        feedback_timeout_sec: float | None = None,
    ) -> TaskHandle:
        """Start a task; returns once the Task Manager has it (accepted, queued, running or
        ended).

        The options (None: the task's declaration): `priority` (higher wins; it may pre-empt
        a running task of at most its priority), `on_conflict` (preempt, queue or reject when
        its resources are busy), `timeout_sec` (start to end), `queue_timeout_sec` (the
        longest wait in the queue), `feedback_timeout_sec` (an action silent this long is
        stalled); a timeout that fires ends it ERROR, error code `timeout`. ValueError says
        what is wrong with one before sending.
        """
        options = request_options(
            priority, on_conflict, timeout_sec, queue_timeout_sec, feedback_timeout_sec
        )
        return self._tasks.start_task(task_name, task_data, task_id, source, options)

    def run_task(
        self,
        task_name: str,
        task_data: dict[str, Any] | str | None = None,
        *,
        timeout_sec: float | None = None,
        task_timeout_sec: float | None = None,
        **options: Any,
    ) -> TaskResult:
        """Start a task and wait for its result, at most `timeout_sec` (None: no limit).

        `options` are start_task's keywords, except its `timeout_sec` (the task's own
        timeout), which is `task_timeout_sec` here.
        """
        handle = self.start_task(task_name, task_data, timeout_sec=task_timeout_sec, **options)
        return handle.result(timeout_sec)

    def start_mission(
        self,
        subtasks: list[Subtask],
        *,
        task_id: str = '',
        source: str = 'python',
        priority: int | None = None,
        on_conflict: OnConflict | str | None = None,
        timeout_sec: float | None = None,
        queue_timeout_sec: float | None = None,
        feedback_timeout_sec: float | None = None,
    ) -> tuple[TaskHandle, list[str]]:
        """Start system/mission; returns its handle and the subtask ids (generated if empty).

        The handle's `subtasks` are handles of the subtasks (feedback, state, result); one
        the mission never reached never ends. The options are start_task's, for the mission
        as one unit (it queues as one; its subtasks hold their own resources as they run).
        """
        options = request_options(
            priority, on_conflict, timeout_sec, queue_timeout_sec, feedback_timeout_sec
        )
        return self._tasks.start_mission(subtasks, task_id, source, options)

    def cancel_tasks(self, task_ids: list[str], *, source: str = 'python') -> TaskResult:
        """Cancel tasks by id through system/cancel_task (whoever started them)."""
        return self.run_task(CANCEL_TASK, {'cancelled_tasks': task_ids}, source=source)

    def reprioritize(
        self,
        task_ids: Sequence[str],
        priority: int,
        *,
        source: str = 'python',
        timeout_sec: float | None = None,
    ) -> TaskResult:
        """Give active tasks a new priority through system/reprioritize, and wait for its result.

        A queued task moves in the queue at once; a running one goes on, and its new priority
        counts for the requests that come after. It ends DONE when every task has it, else
        ERROR; its result has `successful_changes` and `errors` (one line per other id).
        """
        data = {'task_ids': list(task_ids), 'priority': check_priority(priority)}
        return self.run_task(REPRIORITIZE, data, source=source, timeout_sec=timeout_sec)

    def stop(self, *, source: str = 'python') -> TaskResult:
        """system/stop: cancel every task declared with cancel_on_stop."""
        return self.run_task(STOP, {}, source=source)

    def cancel_own(self, handle: TaskHandle, timeout_sec: float) -> bool:
        """Cancel a task this client started, as its client (the task ends CANCELED)."""
        return self._tasks.cancel(handle, timeout_sec)

    # ---- watching ----------------------------------------------------------------------------

    def active_tasks(self, timeout_sec: float | None = None) -> list[ActiveTaskInfo]:
        """The current active tasks (the latest /task_manager/active_tasks message)."""
        return self._active.latest(timeout_sec)

    def active_task_updates(
        self, timeout_sec: float | None = None, until: Future[Any] | None = None
    ) -> Iterator[list[ActiveTaskInfo]]:
        """Every active task list from now on.

        Stops after `timeout_sec` without an update (None: never), or once `until` completes.
        """
        return self._watch.active_task_updates(timeout_sec, until)

    def results(
        self, timeout_sec: float | None = None, until: Future[Any] | None = None
    ) -> Iterator[TaskResult]:
        """Every task result from now on; stops as active_task_updates does."""
        return self._watch.results(timeout_sec, until)

    def updates(
        self, timeout_sec: float | None = None, until: Future[Any] | None = None
    ) -> Iterator[list[ActiveTaskInfo] | TaskResult]:
        """Active task lists and results, in the order they arrive; stops as above."""
        return self._watch.updates(timeout_sec, until)

    def task_events(
        self, timeout_sec: float | None = None, until: Future[Any] | None = None
    ) -> Iterator[TaskEvent]:
        """Every event of every task from this call on; stops as active_task_updates does.

        Events are kept from the call, not from the first `next()`: start the iterator, then
        the tasks whose events it must not miss.
        """
        return self._watch.task_events(timeout_sec, until)

    def on_task_event(self, callback: Callable[[TaskEvent], None]) -> Callable[[], None]:
        """Call `callback(event)` with every task event from now on; returns the unsubscribe.

        It runs on the executor thread: it must return quickly and never wait on the client.
        """
        return self._watch.on_task_event(callback)

    # ---- what the Task Manager keeps ---------------------------------------------------------

    def task_states(
        self, task_ids: Sequence[str] = (), timeout_sec: float | None = None
    ) -> list[TaskState]:
        """The current state of these tasks (active or ended and kept), or of every active one.

        Ids the Task Manager does not know are left out.
        """
        return self._history.task_states(task_ids, timeout_sec)

    def why(self, task_id: str, timeout_sec: float | None = None) -> list[Decision]:
        """Every decision the Task Manager took about a task, oldest first: queued, started
        (after a wait, or pre-empting), refused, pre-empted, timed out, retried,
        reprioritized, each with its reason; empty when it was simply started.

        From its state while it is active, else from the history; TaskManagerError when the
        Task Manager knows no such task.
        """
        return self._history.why(task_id, timeout_sec)

    def recent_results(self, max_results: int = 0) -> list[TaskResult]:
        """Results the Task Manager has kept (oldest first), including from before we started.

        With their stamps, from /task_manager/get_task_states.
        """
        return self._history.recent_results(max_results)

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
        return self._history.history(
            task_name,
            status=status,
            source=source,
            mission_id=mission_id,
            since=since,
            until=until,
            after_sequence=after_sequence,
            limit=limit,
            oldest_first=oldest_first,
            timeout_sec=timeout_sec,
        )

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
        return self._history.stats(
            task_name,
            source=source,
            mission_id=mission_id,
            since=since,
            until=until,
            timeout_sec=timeout_sec,
        )

    def declared_tasks(self) -> list[dict[str, Any]]:
        """The declared tasks and their properties, read from the node's parameters."""
        return declared_tasks(self._services.call)

    # ---- pauses ------------------------------------------------------------------------------

    def pause(
        self, task_ids: Sequence[str], *, source: str = 'python', timeout_sec: float | None = None
    ) -> TaskResult:
        """Pause active tasks by id through system/pause, and wait for its result.

        It ends DONE when every task is paused (one already paused counts), else ERROR; its
        result has `successful_pauses` and `errors` (one line per other id). `timeout_sec`:
        as for run_task (None: no limit).
        """
        return self._pauses.pause(task_ids, source=source, timeout_sec=timeout_sec)

    def resume(
        self, task_ids: Sequence[str], *, source: str = 'python', timeout_sec: float | None = None
    ) -> TaskResult:
        """Resume paused tasks by id through system/resume, and wait for its result.

        It ends DONE when every task runs again, else ERROR; its result has
        `successful_resumes` and `errors` (one line per other id, e.g. one not paused).
        """
        return self._pauses.resume(task_ids, source=source, timeout_sec=timeout_sec)

    def confirm(
        self, task_id: str, *, reject: bool = False, comment: str = '', source: str = 'python'
    ) -> ConfirmAnswer:
        """Answer a waiting system/confirm: confirmed, it ends DONE; rejected, ERROR `rejected`;
        its result names `source` (`by`) and `comment`. Start one with start_task."""
        return self._confirmations.confirm(task_id, reject, comment, source)

    # ---- schedules ---------------------------------------------------------------------------

    def schedule_task(
        self,
        task_name: str,
        task_data: dict[str, Any] | str | None = None,
        when: When | None = None,
        *,
        schedule_id: str = '',
        source: str = 'python',
        timeout_sec: float | None = None,
        priority: int | None = None,
        on_conflict: OnConflict | str | None = None,
        task_timeout_sec: float | None = None,
        queue_timeout_sec: float | None = None,
        feedback_timeout_sec: float | None = None,
        **when_keywords: Unpack[WhenKeywords],
    ) -> TaskResult:
        """Schedule a task through system/schedule; its result has `schedule_id` and
        `next_run` (see scheduled_next_run), or `message` saying why it was refused.

        `when` (a When), or its fields as keywords (`period=3600`, `cron='0 2 * * *'`, ...),
        says when it runs; ValueError says what is wrong before sending. `timeout_sec` is
        the longest wait for system/schedule's result. Each run is started with start_task's
        options (None: the task's declaration), the run's own timeout being
        `task_timeout_sec` here, as in run_task.
        """
        when = when_of(when, when_keywords)
        options = request_options(
            priority, on_conflict, task_timeout_sec, queue_timeout_sec, feedback_timeout_sec
        )
        return self._schedules.schedule_task(
            task_name,
            task_data,
            when,
            schedule_id=schedule_id,
            source=source,
            timeout_sec=timeout_sec,
            options=options,
        )

    def schedule_mission(
        self,
        subtasks: Sequence[Subtask],
        when: When | None = None,
        *,
        schedule_id: str = '',
        source: str = 'python',
        timeout_sec: float | None = None,
        priority: int | None = None,
        on_conflict: OnConflict | str | None = None,
        task_timeout_sec: float | None = None,
        queue_timeout_sec: float | None = None,
        feedback_timeout_sec: float | None = None,
        **when_keywords: Unpack[WhenKeywords],
    ) -> TaskResult:
        """Schedule system/mission with these subtasks, as schedule_task does.

        Each run makes its own subtask ids; a subtask id given is refused for a schedule that
        may run more than once, since two runs cannot share task ids. The options are
        schedule_task's, for each run's mission as one unit (as start_mission's).
        """
        when = when_of(when, when_keywords)
        options = request_options(
            priority, on_conflict, task_timeout_sec, queue_timeout_sec, feedback_timeout_sec
        )
        return self._schedules.schedule_mission(
            subtasks,
            when,
            schedule_id=schedule_id,
            source=source,
            timeout_sec=timeout_sec,
            options=options,
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
        return self._schedules.unschedule(schedule_ids, source=source, timeout_sec=timeout_sec)

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
        return self._schedules.enable_schedules(
            schedule_ids, enabled, source=source, timeout_sec=timeout_sec
        )

    def schedules(
        self, schedule_ids: Sequence[str] | None = None, timeout_sec: float | None = None
    ) -> list[ScheduleInfo]:
        """These schedules (ids that are not schedules are left out), or every one (None)."""
        return self._schedules.schedules(schedule_ids, timeout_sec)
