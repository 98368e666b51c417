"""`Fleet`: the console's view of every robot on the broker, and its fleet history.

It follows every robot under the prefix through one FleetClient (a persistent session: the
broker keeps what robots send while the console is away) and stores each robot's results in
the FleetHistory exactly once, in order (store/ingest.py): a result is acknowledged to the
broker only once it is stored (or refused for good), so that one received while the database
is away stays with the broker, and one received twice is stored once (its robot, sequence and
task id are its key).

Requests to robots go through `client` (the FleetClient's calls: cancel, pause, resume,
reprioritize, confirm, stop, ...), each checked first: a robot id and task ids that can name
something, a robot known and ONLINE. Starts and STOP ALL are the Fleet's own.

Threads: the MQTT client's (documents in, never waiting), one that stores results (in batches,
retrying while the database is away) and a small pool for reads of the database (a robot's
last stored result). Callbacks of `on_change` run on those threads and must not wait.
"""

import logging
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import dataclass
from functools import cached_property
from typing import Any, Unpack

from task_manager_mqtt.fleet_client import FleetClient
from task_manager_mqtt.fleet_types import TIMEOUT_SEC, FleetError, StartOptions
from task_manager_mqtt.settings import DEFAULT_MAX_PAYLOAD_BYTES, DEFAULT_PREFIX
from task_manager_mqtt.topics import TopicName

from task_manager.core.bounds import FLEET_RESULTS_HELD_MAX, ids_problem
from task_manager.core.text.request_text import request_problem
from task_manager.protocol.errors import RefusalCode
from task_manager_console.bad_messages import BadMessages
from task_manager_console.robots import (
    BadDocumentError,
    ConnectionState,
    RobotState,
    robot_id_problem,
)
from task_manager_console.store.fleet_history import DatabaseUnavailable, FleetHistory
from task_manager_console.store.ingest import Ingest
from task_manager_console.store.rows import Document, document_of

LOG = logging.getLogger('task_manager_console.fleet')
CONSOLE_CLIENT_ID = 'task-manager-console'
"""The console's MQTT client id; a broker that ties ids to accounts uses the account's name."""
READERS = 2
"""Threads of the reads of the database (last results)."""


@dataclass(frozen=True)
class Change:
    """One change of the fleet: a robot's new state, and the result just stored, if any."""

    robot: RobotState
    row: Document | None = None
    """The row of a result newly stored, when that is the change."""

    @cached_property
    def result(self) -> Document | None:
        """The result newly stored as a fleet history document (made when first asked: most
        changes go to no event stream)."""
        return None if self.row is None else document_of(self.row)


class Fleet:
    """Every robot under the prefix and its results; use as a context manager, or call
    `start()` then `close()`."""

    def __init__(
        self,
        broker_url: str,
        history: FleetHistory,
        *,
        prefix: str = DEFAULT_PREFIX,
        client_id: str = CONSOLE_CLIENT_ID,
        password: str = '',
        ca_file: str = '',
        events: bool = False,
        max_message_bytes: int = DEFAULT_MAX_PAYLOAD_BYTES,
    ) -> None:
        """`broker_url`, `password`, `ca_file`: as FleetClient's; its own account (one account
        holds one connection). `events`: also follow every task event (see `on_event`).
        `max_message_bytes`: a robot's message larger than this is ignored (counted)."""
        self.history = history
        self.client = FleetClient(
            broker_url,
            prefix=prefix,
            client_id=client_id,
            events=events,
            ca_file=ca_file,
            password=password,
            hold_results=True,
            receive_maximum=FLEET_RESULTS_HELD_MAX,
            max_message_bytes=max_message_bytes,
            check_request=self._check,
        )
        self.bad_messages = BadMessages(LOG)
        self.results_stored = 0
        """Results stored since the start (each once)."""
        self.results_received = 0
        """Deliveries of results since the start (duplicates and bad ones too)."""
        self._robots: dict[str, RobotState] = {}
        # reentrant: a condition of wait_until may read `robots`
        self._lock = threading.RLock()
        self._progress = threading.Condition(self._lock)
        """Notified at each change: of a robot, a result received or stored, the database."""
        self._callbacks: list[Callable[[Change], None]] = []
        self._ingest = Ingest(
            history,
            on_stored=self._on_stored,
            on_bad=lambda robot_id, why: self._on_bad_message(robot_id, TopicName.RESULT, why),
            on_database=self._on_database,
        )
        self._readers = ThreadPoolExecutor(READERS, thread_name_prefix='fleet-reads')
        self.client.on_held_result(self._on_result)
        self.client.on_state(self._on_state)
        self.client.on_bad_message(self._on_bad_message)

    def __enter__(self) -> 'Fleet':
        self.start()
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def start(self, timeout_sec: float = TIMEOUT_SEC) -> None:
        """Start storing, connect and follow (once per Fleet); FleetError if the broker is not
        reached in time."""
        self._ingest.start()
        try:
            self.client.connect(timeout_sec)
        except FleetError:
            self._ingest.stop()
            self._readers.shutdown(wait=False)
            raise

    def close(self) -> None:
        """Disconnect (the broker keeps the session), then stop storing: results not stored
        yet are not acknowledged, so the broker delivers them again at the next start."""
        self._ingest.stop()  # the batch being stored is acknowledged before disconnecting
        self.client.close()
        self._readers.shutdown(wait=True, cancel_futures=True)  # reads of the database: short

    # ---- what is known ------------------------------------------------------------------------

    @property
    def robots(self) -> dict[str, RobotState]:
        """Every robot seen, by id (a copy: the states themselves never change)."""
        with self._lock:
            return dict(self._robots)

    def robot(self, robot_id: str) -> RobotState | None:
        with self._lock:
            return self._robots.get(robot_id)

    def on_change(self, callback: Callable[[Change], None]) -> Callable[[], None]:
        """`callback(change)` at each change of a robot and each result stored; returns the
        function that removes it. It runs on the console's threads and must not wait; changes
        of one robot may reach it out of order from two threads (its newest state is
        `robot(robot_id)`)."""
        with self._lock:
            self._callbacks.append(callback)

        def remove() -> None:
            with self._lock:
                if callback in self._callbacks:
                    self._callbacks.remove(callback)

        return remove

    def on_event(self, callback: Callable[[str, Document], None]) -> None:
        """`callback(robot_id, event)` for every TaskEvent document (with `events=True`)."""
        self.client.on_event(callback)

    @property
    def duplicates(self) -> int:
        """Results received again and not stored again."""
        return self._ingest.duplicates

    @property
    def database_up(self) -> bool:
        """False while stores fail (results wait with the broker meanwhile)."""
        return self._ingest.database_up

    def results_waiting(self) -> int:
        """Results received and not yet stored (nor acknowledged)."""
        return self._ingest.waiting()

    def wait_for(
        self, condition: Callable[[dict[str, RobotState]], bool], timeout_sec: float
    ) -> bool:
        """Wait until `condition(robots)` holds (checked at each change); whether it did."""
        return self.wait_until(lambda: condition(dict(self._robots)), timeout_sec)

    def wait_until(self, condition: Callable[[], bool], timeout_sec: float) -> bool:
        """Wait until `condition()` holds, checked at each change of a robot, each result
        received or stored, each bad message and each change of `database_up`; whether it did."""
        with self._progress:
            return self._progress.wait_for(condition, timeout_sec)

    # ---- acting on robots ---------------------------------------------------------------------

    def start_task(
        self,
        robot_id: str,
        task_name: str,
        task_data: Document | None = None,
        *,
        task_id: str = '',
        source: str = '',
        reply_timeout_sec: float = TIMEOUT_SEC,
        **options: Unpack[StartOptions],
    ) -> Document:
        """Start a task on an ONLINE robot; the robot's reply (task_id, duplicate, task), within
        `reply_timeout_sec` (`options`: FleetClient.start_task's, `timeout_sec` the task's).
        FleetError: `invalid_request`, `unknown_robot`, `robot_offline`, or the robot's own."""
        started = self.client.start_task(
            robot_id, task_name, task_data, task_id=task_id, source=source, **options
        )
        return started.accepted(reply_timeout_sec)

    def start_mission(
        self,
        robot_id: str,
        subtasks: list[Document],
        *,
        task_id: str = '',
        source: str = '',
        reply_timeout_sec: float = TIMEOUT_SEC,
        **options: Unpack[StartOptions],
    ) -> Document:
        """Start a mission on an ONLINE robot (`subtasks` as FleetClient.start_mission's); the
        robot's reply (task_id, subtask_ids, duplicate, task)."""
        started = self.client.start_mission(
            robot_id, subtasks, task_id=task_id, source=source, **options
        )
        return started.accepted(reply_timeout_sec)

    def stop_all(self, timeout_sec: float = TIMEOUT_SEC) -> dict[str, Document]:
        """system/stop on every robot at once; each robot's reply document (`ok`, and `task`
        or `error`), an OFFLINE robot's being `robot_offline` (it was not asked)."""
        answers: dict[str, Document] = {}
        asked: dict[str, Future[Document]] = {}
        for robot_id in sorted(self.robots):
            try:
                asked[robot_id] = self.client.request(robot_id, 'stop')
            except FleetError as refused:  # not ONLINE: not asked
                answers[robot_id] = _error(refused)
        deadline = time.monotonic() + timeout_sec
        for robot_id, reply in asked.items():
            try:
                answers[robot_id] = reply.result(max(deadline - time.monotonic(), 0.0))
            except FutureTimeout:
                message = f'no reply of {robot_id} within {timeout_sec} s'
                answers[robot_id] = _error(FleetError(message, RefusalCode.TIMEOUT))
            except FleetError as error:
                answers[robot_id] = _error(error)
        return dict(sorted(answers.items()))

    def refresh_schedules(self, robot_id: str) -> Future[Document]:
        """Ask the robot for its schedules again; its state's `schedules` holds them once its
        reply (the future's) has come. Nothing waits for it."""
        reply = self.client.request(robot_id, 'schedules', schedule_ids=[])
        reply.add_done_callback(lambda done: self._on_schedules(robot_id, done))
        return reply

    def _check(self, robot_id: str, _: str, fields: dict[str, Any]) -> None:
        """The FleetClient's check of each request: FleetError unless the robot is ONLINE and
        the request's texts and ids are usable."""
        texts = [fields.get(name) or '' for name in ('task_id', 'task_name', 'source')]
        problem = robot_id_problem(robot_id) or request_problem(*texts)
        task_ids = fields.get('task_ids')
        if not problem and task_ids is not None:
            problem = ids_problem('task_ids', task_ids) or next(
                (p for i in task_ids if (p := request_problem(i, '', '') or '')), ''
            )
        if problem:
            raise FleetError(problem, RefusalCode.INVALID_REQUEST)
        robot = self.robot(robot_id)
        if robot is None:
            raise FleetError(
                f'no robot {robot_id!r} is known on the broker', RefusalCode.UNKNOWN_ROBOT
            )
        if not robot.online:
            raise _offline(robot)

    # ---- on the MQTT client's thread: never wait ----------------------------------------------

    def _on_result(self, robot_id: str, task: Document, acknowledge: Callable[[], None]) -> None:
        self._ingest.put(robot_id, task, acknowledge)
        with self._progress:
            self.results_received += 1
            self._progress.notify_all()

    def _on_state(self, robot_id: str, name: str, document: Document | None) -> None:
        if problem := robot_id_problem(robot_id):
            self.bad_messages.count(robot_id, name, problem)
            return
        if document is None:  # a retained document cleared: the last one known stays
            return
        with self._lock:
            old = self._robots.get(robot_id)
            state = old or RobotState(robot_id)
            try:
                if name == TopicName.CONNECTION:
                    state = state.with_connection(document)
                elif name == TopicName.TASKS:
                    state = state.with_tasks(document)
                elif name == TopicName.ACTIVE_TASKS:
                    state = state.with_active(document)
            except BadDocumentError as error:
                why = str(error)
            else:
                why = ''
                self._robots[robot_id] = state
        if why:
            self._on_bad_message(robot_id, name, why)
            return
        if old is None:
            self._readers.submit(self._read_last_result, robot_id)
        if state.online and not (old and old.online):
            self.refresh_schedules(robot_id)
        self._notify(Change(state))

    def _on_bad_message(self, robot_id: str, name: str, why: str) -> None:
        count = self.bad_messages.count(robot_id, name, why)
        with self._progress:
            robot = self._robots.get(robot_id)
            if robot is not None:
                self._robots[robot_id] = robot.with_fields(bad_messages=count)
            self._progress.notify_all()

    # ---- on the storing thread ---------------------------------------------------------------

    def _on_database(self, _: bool) -> None:
        with self._progress:
            self._progress.notify_all()

    def _on_stored(self, rows: list[Document]) -> None:
        """A batch stored: each robot's count and last result, then a change per row."""
        changes: list[Change] = []
        with self._lock:
            self.results_stored += len(rows)
            for row in rows:
                robot_id = row['robot_id']
                robot = self._robots.get(robot_id) or RobotState(robot_id)
                robot = robot.with_fields(results_stored=robot.results_stored + 1)
                self._robots[robot_id] = robot
                changes.append(Change(robot, row))
            for change in {c.robot.robot_id: c for c in changes}.values():  # each one's last
                robot = self._robots[change.robot.robot_id]
                self._robots[robot.robot_id] = robot.with_fields(last_result=change.result)
        for change in changes:
            self._notify(change)

    # ---- slower reads, on the readers' threads ------------------------------------------------

    def _read_last_result(self, robot_id: str) -> None:
        try:
            last = self.history.last_result(robot_id)
        except DatabaseUnavailable as error:
            LOG.debug('last result of %s not read: %s', robot_id, error)
            return
        if last is None:
            return
        with self._lock:
            robot = self._robots.get(robot_id)
            if robot is None or robot.last_result is not None:
                return
            robot = self._robots[robot_id] = robot.with_fields(last_result=last)
        self._notify(Change(robot))

    def _on_schedules(self, robot_id: str, reply: Future[Document]) -> None:
        try:
            document = reply.result()
        except FleetError as error:  # not sent
            LOG.info('the schedules of %s were not asked: %s', robot_id, error)
            return
        schedules = document.get('schedules')
        if not document.get('ok') or not isinstance(schedules, list):
            LOG.info('the schedules of %s were not read: %s', robot_id, document.get('error'))
            return
        with self._lock:
            robot = self._robots.get(robot_id)
            if robot is None:
                return
            robot = self._robots[robot_id] = robot.with_fields(schedules=schedules)
        self._notify(Change(robot))

    def _notify(self, change: Change) -> None:
        with self._progress:
            callbacks = list(self._callbacks)
            self._progress.notify_all()
        for callback in callbacks:
            try:
                callback(change)
            except Exception:  # a callback's bug must not stop the console
                LOG.exception('a change callback failed')


def _offline(robot: RobotState) -> FleetError:
    state = str(robot.connection_state)
    if robot.connection_state == ConnectionState.ONLINE:
        state = 'ONLINE but its bridge reaches no Task Manager'
    since = f' since {robot.since.isoformat()}' if robot.since else ''
    return FleetError(f'robot {robot.robot_id} is {state}{since}', RefusalCode.ROBOT_OFFLINE)


def _error(error: FleetError) -> Document:
    return {'ok': False, 'error': {'code': error.code, 'message': str(error)}}
