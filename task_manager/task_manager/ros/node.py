"""The `task_manager` node: declared tasks, ExecuteTask, active tasks and results."""

import sqlite3
from collections.abc import Sequence
from typing import Any

from rclpy.node import Node
from rclpy.task import Future
from task_manager_msgs.action import ExecuteTask, StartTask
from task_manager_msgs.msg import ActiveTask, ActiveTaskArray, TaskDoneResult
from task_manager_msgs.srv import (
    ConfirmTask,
    GetSchedules,
    GetTaskResults,
    GetTaskStates,
    QueryTaskHistory,
)

from task_manager.core.history.rows import HistoryRow
from task_manager.core.history.store import HistoryQuery
from task_manager.core.names import (
    ACTIVE_TASKS_TOPIC,
    CONFIRM_TASK_SERVICE,
    EXECUTE_TASK_ACTION,
    GET_SCHEDULES_SERVICE,
    GET_TASK_RESULTS_SERVICE,
    GET_TASK_STATES_SERVICE,
    IDS_MAX,
    NODE_NAME,
    QUERY_TASK_HISTORY_SERVICE,
    RESULTS_TOPIC,
    START_TASK_ACTION,
    SYSTEM_TASK_NAMES,
)
from task_manager.core.task import TaskRecord, TaskRequest
from task_manager.core.task_spec import TaskKind, TaskSpec
from task_manager.messages.task_messages import (
    active_task_msg,
    history_query,
    options_of_message,
    result_fields,
    result_msg,
    result_msg_of_row,
    schedule_msg,
    task_state_msg,
    task_state_of_row,
)
from task_manager.rclpy_tools import qos
from task_manager.rclpy_tools.cleanup import destroy_waitables
from task_manager.rclpy_tools.futures import wait_until_ready
from task_manager.rclpy_tools.log import NodeLog
from task_manager.ros.instances import InstanceWatch
from task_manager.ros.interfaces import load_interface
from task_manager.ros.parameters import read_settings, read_task_specs
from task_manager.ros.recording.history_writer import open_history
from task_manager.ros.recording.task_changes import TaskChanges
from task_manager.ros.recording.task_events import TaskEventStream
from task_manager.ros.running.action_runner import ActionTaskRunner
from task_manager.ros.running.admission_control import AdmissionControl
from task_manager.ros.running.attempts import Attempts
from task_manager.ros.running.deadline_timer import DeadlineTimer
from task_manager.ros.running.dispatcher import TaskDispatcher
from task_manager.ros.running.execution import RunnerTimeouts, TaskCatalog, TaskRunner
from task_manager.ros.running.pause_control import PauseControl
from task_manager.ros.running.scheduler import TaskScheduler
from task_manager.ros.running.service_runner import ServiceTaskRunner
from task_manager.ros.running.task_run import Runs
from task_manager.ros.serving.action_services_server import ActionServicesServer
from task_manager.ros.serving.goal_binding import GoalTaskBinding
from task_manager.ros.serving.task_servers import create_task_servers
from task_manager.ros.system import create_system_runners
from task_manager.ros.system.confirm import ConfirmRunner

# Beyond the longest cancel_timeout of the active tasks, what a shutdown may take.
SHUTDOWN_MARGIN_SEC = 1.0
# Retention runs once a minute and deletes at most a batch, so that it never holds up dispatch.
PRUNE_PERIOD_SEC = 60.0
PRUNE_BATCH = 5000
# How long the ends of tasks closed at start wait for a results subscriber to match.
CLOSED_PUBLISH_WAIT_SEC = 5.0
# A warning about a request that may keep coming is logged at most this often.
LOG_THROTTLE_SEC = 10.0
RESTARTED_WHILE_RUNNING = (
    'the Task Manager stopped while this task ran (it was restarted); the task may or may not '
    'have finished on its server'
)


class TaskManagerNode(Node):
    """Serves the Task Manager's public ROS interfaces.

    Raises ConfigurationError from the constructor when the parameters are unusable. It
    announces itself at once (see instances.py) and serves from `serve()` on.
    """

    def __init__(self) -> None:
        super().__init__(
            NODE_NAME,
            allow_undeclared_parameters=True,
            automatically_declare_parameters_from_overrides=True,
        )
        self._log = NodeLog.of(self)
        qos.drop_qos_events(self, self._parameter_event_publisher)
        self.instances = InstanceWatch(self)
        self.settings = read_settings(self)
        self._specs = read_task_specs(self, reserved_names=set(SYSTEM_TASK_NAMES))
        user_runners = [self._create_runner(spec, self.settings.timeouts) for spec in self._specs]
        # key: task id, value: its entry in active_tasks, built once and kept while it runs
        self._active_task_msgs: dict[str, ActiveTask] = {}
        self.history = open_history(self.settings.history_path, self._log)
        self._events = TaskEventStream(
            self, self.settings.publish_task_events, self.settings.feedback_rate_hz
        )
        # what runs the tasks, each part beside the others (docs/architecture.md)
        self.catalog = TaskCatalog()
        runs = Runs()
        changes = TaskChanges(
            self, self._events, self.history, self, lambda: [r.record for r in runs.listed()]
        )
        timer = DeadlineTimer(self)
        attempts = Attempts(self, self.catalog, changes, timer)
        admission = AdmissionControl(
            self,
            runs,
            changes,
            attempts,
            timer,
            self.settings.max_queued,
            self.settings.source_priorities,
        )
        self.dispatcher = TaskDispatcher(self, self.catalog, runs, changes, admission, attempts)
        pauses = PauseControl(self, runs, changes, attempts)
        self.scheduler = TaskScheduler(self, self.dispatcher, self.history.schedule_store())
        self._confirmations = ConfirmRunner(self, self.dispatcher, self.history)
        self._runners = [
            *user_runners,
            *create_system_runners(
                self, self.dispatcher, pauses, admission, self.catalog, self.scheduler
            ),
            self._confirmations,
        ]
        self.catalog.add(self._runners)
        self._goals = GoalTaskBinding(self, self.dispatcher)
        self._shutting_down = False

    def serve(self) -> None:
        """Serve ExecuteTask and publish active tasks and results (once, when no twin is seen)."""
        self._active_publisher = self.create_publisher(
            ActiveTaskArray,
            ACTIVE_TASKS_TOPIC,
            qos.ACTIVE_TASKS,
            event_callbacks=qos.without_qos_events(),
        )
        self._result_publisher = self.create_publisher(
            TaskDoneResult, RESULTS_TOPIC, qos.RESULTS, event_callbacks=qos.without_qos_events()
        )
        self._results_service = self.create_service(
            GetTaskResults, GET_TASK_RESULTS_SERVICE, self._get_task_results
        )
        self._states_service = self.create_service(
            GetTaskStates, GET_TASK_STATES_SERVICE, self._get_task_states
        )
        self._history_service = self.create_service(
            QueryTaskHistory, QUERY_TASK_HISTORY_SERVICE, self._query_task_history
        )
        self._schedules_service = self.create_service(
            GetSchedules, GET_SCHEDULES_SERVICE, self._get_schedules
        )
        self._confirm_service = self.create_service(
            ConfirmTask, CONFIRM_TASK_SERVICE, self._confirmations.answer_service
        )
        self._events.open()
        self._execute_server = ActionServicesServer(
            self,
            ExecuteTask,
            EXECUTE_TASK_ACTION,
            execute=self._execute_task,
            cancel=self._goals.cancel_callback,
        )
        self._start_server = ActionServicesServer(
            self,
            StartTask,
            START_TASK_ACTION,
            execute=self._start_task,
            cancel=self._goals.cancel_callback,
        )
        self._task_servers = (
            create_task_servers(self, self.dispatcher, [r.spec for r in self._runners])
            if self.settings.enable_task_servers
            else []
        )
        self.publish_active([])
        self._close_unfinished()
        self._prune_history()
        self._prune_timer = self.create_timer(PRUNE_PERIOD_SEC, self._prune_history)
        self.scheduler.start()
        self._log.info(
            f'Task Manager ready with {len(self._specs)} task(s): '
            + ', '.join(spec.task_name for spec in self._specs)
        )

    def _close_unfinished(self) -> None:
        """Tasks that were running when the node died end now, ERROR, stored and published once."""
        closed = self.history.close_unfinished(RESTARTED_WHILE_RUNNING)
        if closed:
            self._spawn(self._publish_closed(closed))
            self._log.warning(
                f'{len(closed)} task(s) were running when the Task Manager stopped; ended ERROR: '
                + ', '.join(f'{r.task_id} ({r.task_name})' for r in closed)
            )
        where = self.history.path
        self._log.info(f'task history: {where}')

    def _prune_history(self) -> None:
        """One batch of retention (history_max_results, history_max_age_days,
        history_max_bytes)."""
        try:
            self.history.prune(
                self.settings.history_max_results,
                self.settings.history_max_age_days,
                batch=PRUNE_BATCH,
                max_bytes=self.settings.history_max_bytes,
            )
        except sqlite3.Error as error:
            self._log.warning(f'cannot prune the task history: {error}')

    async def _publish_closed(self, rows: list[HistoryRow]) -> None:
        """Publish the ends of tasks closed at start once a subscriber has matched (bounded):
        published at once, they would reach nobody, as discovery takes a moment."""
        await wait_until_ready(
            self,
            lambda: self._result_publisher.get_subscription_count() > 0,
            CLOSED_PUBLISH_WAIT_SEC,
        )
        for row in rows:
            self._result_publisher.publish(result_msg_of_row(row))

    async def shut_down(self, stopped: Future[Any]) -> None:
        """Cancel every active task on its server, publish the results, then complete `stopped`.

        A robot must not keep driving once its Task Manager is gone.
        """
        if self._shutting_down:
            return
        self._shutting_down = True
        self.scheduler.stop()
        records = self.dispatcher.records()
        bound_sec = SHUTDOWN_MARGIN_SEC + max(
            (r.spec.cancel_timeout_sec for r in records), default=0.0
        )
        self._log.info(f'shutting down: cancelling {len(records)} active task(s)')
        clean = await self.dispatcher.close('the Task Manager is shutting down', bound_sec)
        if not stopped.done():
            stopped.set_result(clean)

    def destroy_node(self) -> None:
        """Destroy action servers and clients first (see destroy_waitables); close the history."""
        destroy_waitables(self)
        self.close_history()
        super().destroy_node()

    def close_history(self) -> None:
        """Write what the history holds buffered, and close it (again: nothing more)."""
        history = getattr(self, 'history', None)  # None when the constructor failed before it
        if history is not None:
            try:
                history.flush()
            except sqlite3.Error as error:
                self._log.error(f'cannot write the task history at shutdown: {error}')
            history.close()

    def _create_runner(self, spec: TaskSpec, timeouts: RunnerTimeouts) -> TaskRunner:
        interface_class = load_interface(spec)
        if spec.kind is TaskKind.ACTION:
            return ActionTaskRunner(self, spec, interface_class, timeouts)
        return ServiceTaskRunner(self, spec, interface_class, timeouts)

    def _spawn(self, coroutine: Any) -> None:
        assert self.executor is not None, 'the node must be added to an executor'
        self.executor.create_task(coroutine)

    # ---- TaskReporter ----------------------------------------------------------------------

    def publish_active(self, records: list[TaskRecord]) -> None:
        messages = []
        for record in records:
            message = self._active_task_msgs.get(record.task_id)
            if message is None:
                message = self._active_task_msgs[record.task_id] = active_task_msg(record)
            elif message.task_status != record.status:
                message.task_status = str(record.status)
            if record.is_final:  # shown for the last time
                del self._active_task_msgs[record.task_id]
            messages.append(message)
        self._active_publisher.publish(ActiveTaskArray(active_tasks=messages))

    def publish_result(self, record: TaskRecord) -> None:
        self._result_publisher.publish(result_msg(record))

    def _get_task_results(
        self, request: GetTaskResults.Request, response: GetTaskResults.Response
    ) -> GetTaskResults.Response:
        """The newest results from the history (at most results_history_size), oldest first."""
        size = self.settings.results_history_size
        limit = min(request.max_results, size) if request.max_results else size
        rows = self.history.query(HistoryQuery(limit=limit))
        response.results = [result_msg_of_row(row) for row in reversed(rows)]
        return response

    def _get_task_states(
        self, request: GetTaskStates.Request, response: GetTaskStates.Response
    ) -> GetTaskStates.Response:
        active = [task_state_msg(record) for record in self.dispatcher.records()]
        if not request.task_ids:
            response.tasks = active
            return response
        by_id = {state.task_id: state for state in active}
        # each id not active costs a history query
        for task_id in self._first_ids(request.task_ids, 'get_task_states', 'tasks'):
            if task_id in by_id:
                response.tasks.append(by_id[task_id])
            elif task_id and (stored := self.history.query(HistoryQuery(task_id=task_id, limit=1))):
                response.tasks.append(task_state_of_row(stored[0]))
        return response

    def _first_ids(self, ids: Sequence[str], service: str, what: str) -> Sequence[str]:
        """The first IDS_MAX of the ids `service` was asked for; a warning when there were more
        (from this one place, so that rclpy's throttle, which keys on where it is called, makes
        a flood on either service one line a while)."""
        if len(ids) > IDS_MAX:
            self.get_logger().warning(
                f'{service} asked for {len(ids)} {what}: the first {IDS_MAX} answered, the rest '
                'left out',
                throttle_duration_sec=LOG_THROTTLE_SEC,
            )
        return ids[:IDS_MAX]

    def _query_task_history(
        self, request: QueryTaskHistory.Request, response: QueryTaskHistory.Response
    ) -> QueryTaskHistory.Response:
        rows = self.history.query(history_query(request))
        response.tasks = [task_state_of_row(row) for row in rows]
        return response

    def _get_schedules(
        self, request: GetSchedules.Request, response: GetSchedules.Response
    ) -> GetSchedules.Response:
        """Every schedule (or those asked for, in the order asked: the first IDS_MAX), with its
        runs."""
        # each one asked is a schedule in the answer
        asked = self._first_ids(request.schedule_ids, 'get_schedules', 'schedules')
        wanted = list(asked) or self.scheduler.book.ids()
        found = (self.scheduler.book.get(schedule_id) for schedule_id in wanted)
        response.schedules = [schedule_msg(*item) for item in found if item is not None]
        return response

    # ---- /task_manager/execute_task ----------------------------------------------------------

    async def _execute_task(self, goal_handle: Any) -> ExecuteTask.Result:
        goal = goal_handle.request
        request = TaskRequest(goal.task_id, goal.task_name, goal.source, goal.task_data)
        record = await self._goals.run(goal_handle, request)
        return ExecuteTask.Result(**result_fields(record))

    async def _start_task(self, goal_handle: Any) -> StartTask.Result:
        """ExecuteTask with options (priority, on_conflict, timeouts): the same result."""
        goal = goal_handle.request
        options = options_of_message(goal.options)
        request = TaskRequest(
            goal.task_id, goal.task_name, goal.source, goal.task_data, options=options
        )
        record = await self._goals.run(goal_handle, request)
        return StartTask.Result(**result_fields(record))
