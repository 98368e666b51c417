"""`TaskManagerClient`: start, watch, cancel, pause and schedule tasks of a running Task Manager.

The client generates every task id itself and takes a task's outcome from whichever comes
first, the ExecuteTask result or the task's message on /task_manager/results, so a lost
reply on the network never leaves a script waiting: every wait is bounded.

Stamps and feedback come from /task_manager/task_events, which a client subscribes to once,
on first use (starting a task, asking for feedback or events); each event goes to the
handle of its task by id. A client that joins late asks /task_manager/get_task_states.

A request may carry options (priority, on_conflict, timeouts; None: the task's declaration):
with any, it goes to /task_manager/start_task, else to ExecuteTask as it always did.

The client is made of parts, one per concern: it holds the connection, the tasks it started
(tasks.py) and the query services, and gets its other methods from its mixins, each of which
reaches the Task Manager only through what `ClientParts` says (a service call, a system task
run to its end): watching what the node publishes (watching.py), what it keeps and declares
(history.py), interventions (interventions.py) and schedules (scheduling.py).
"""

import time
from collections.abc import Callable, Collection, Sequence
from typing import Any

from task_manager.client.connection import DEFAULT_TIMEOUT_SEC, Connection
from task_manager.client.handle import TaskHandle
from task_manager.client.hearing import HearingWatch
from task_manager.client.history import HistoryQueries
from task_manager.client.interventions import Interventions
from task_manager.client.listeners import Callback
from task_manager.client.missions import Subtask
from task_manager.client.records import TaskResult
from task_manager.client.scheduling import Scheduling
from task_manager.client.services import ServiceCalls
from task_manager.client.tasks import NO_OPTIONS, Tasks, check_priority, request_options
from task_manager.client.watching import ActiveTasks, Watching
from task_manager.core.admission.options import OnConflict
from task_manager.core.bounds import SECONDS
from task_manager.core.names import CANCEL_TASK, REPRIORITIZE, STOP
from task_manager.rclpy_tools.log import NodeLog


class TaskManagerClient(Watching, HistoryQueries, Interventions, Scheduling):
    """A client of the Task Manager with its own node, spun in a background thread.

    Use it as a context manager, or call `close()`.
    """

    def __init__(
        self, node_name: str = 'task_manager_client', timeout_sec: float = DEFAULT_TIMEOUT_SEC
    ) -> None:
        SECONDS.check('timeout_sec', timeout_sec)  # threading's waits take no infinity
        self._connection = Connection(node_name, timeout_sec)
        self.node = self._connection.node
        self._active = ActiveTasks(self._connection)
        self._tasks = Tasks(self._connection, self._active)
        self._results = self._tasks.results
        self._events = self._tasks.events
        self._services = ServiceCalls(self._connection)
        self._hearing = HearingWatch(self._connection, serving=self._served)
        self._connection.start()

    def _served(self) -> bool:
        """Whether the node serves this client: its ExecuteTask server, and each service this
        client has used, have met it (see HearingWatch)."""
        return self._tasks.serving() and self._services.all_met()

    @property
    def timeout_sec(self) -> float:
        """How long a call waits when not told."""
        return self._connection.timeout_sec

    @timeout_sec.setter
    def timeout_sec(self, timeout_sec: float) -> None:
        SECONDS.check('timeout_sec', timeout_sec)
        self._connection.timeout_sec = timeout_sec

    # ---- lifecycle and connection ------------------------------------------------------------

    def __enter__(self) -> 'TaskManagerClient':
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def close(self) -> None:
        self._connection.close()

    def wait_until_available(
        self,
        timeout_sec: float | None = None,
        *,
        events: bool = False,
        services: Collection[str] = (),
    ) -> None:
        """Wait for the Task Manager's action server and topics; TaskManagerUnavailable if not.

        With `events`, also subscribe to /task_manager/task_events now and wait until it is
        connected, if the Task Manager publishes it (see `events_connected`). With `services`
        (names of its services, e.g. `GET_TASK_STATES_SERVICE`), also until each has met this
        client, within `timeout_sec` of the rest.
        """
        deadline = time.monotonic() + (self.timeout_sec if timeout_sec is None else timeout_sec)
        self._tasks.wait_until_available(timeout_sec, events=events)
        self._services.wait_until_ready(services, max(0.0, deadline - time.monotonic()))

    @property
    def connected(self) -> bool:
        """Whether a Task Manager is there: its /task_manager/active_tasks reaches this client.

        It turns False at once when the node stops, and after DDS's lease duration when the
        node's process dies without stopping (5 s: the node's discovery profile).
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
        return self._connection.changes.add(Callback(callback, NodeLog.of(self.node)))

    def on_node_unheard(self, callback: Callable[[float], None]) -> Callable[[], None]:
        """Call `callback(seconds)` when this client is deaf to the Task Manager; returns the
        unsubscribe. The first call starts the checks (a 1 s timer on the executor):

        - this process, held up 4 s or more (stopped, frozen, starved), does not hear the node
          again within 10 s (an answer to a question, and every topic that reached it before);
          `seconds`: how long it was held up;
        - the node's active list has not reached the client for 10 s, and a new participant of
          this process (made for the look, each 30 s) sees it while the client still does not
          10 s later; `seconds`: how long it was lost.

        After a participant (this one or the node's) was held up past the DDS lease, Fast DDS
        can stay one-sided and only a new participant hears the node: the gateways exit for
        their supervisor (see docs/faults-and-shutdown.md). It runs on the executor thread.
        """
        return self._hearing.add(callback)

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

    # ---- what the parts stand on (ClientParts) -----------------------------------------------

    def _call(
        self, service_type: Any, name: str, request: Any, timeout_sec: float | None = None
    ) -> Any:
        return self._services.call(service_type, name, request, timeout_sec)

    def _system_task(
        self, task_name: str, data: dict[str, Any], *, source: str, timeout_sec: float | None
    ) -> TaskResult:
        handle = self._tasks.start_task(task_name, data, '', source, NO_OPTIONS)
        return handle.result(timeout_sec)
