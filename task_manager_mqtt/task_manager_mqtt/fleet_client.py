"""`FleetClient`: the cloud side. Start tasks and missions on robots by id, wait for their
results, follow every robot's connection and active tasks, through one MQTT broker.

Given a client id of its own (stable across runs), it keeps a session on the broker, so
that results robots send while this client is away (a restart, the broker's) wait for it
there; without one, its session ends with its connection. Each robot's results are
told apart by sequence number: one delivered twice (after a reconnection) is passed on once.

A client that keeps the results somewhere (the fleet console's database) holds them
(`hold_results`): each result is acknowledged to the broker only once it is kept, so that the
broker keeps it, and delivers it again at the next connection, until then.
"""

import itertools
import json
import logging
import threading
import uuid
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import replace
from typing import Any, Unpack, cast

import paho.mqtt.client as mqtt
from paho.mqtt.reasoncodes import ReasonCode

from task_manager_mqtt.connection import RECONNECT_MIN_SEC, connect, largest_payload, new_client
from task_manager_mqtt.fleet.publishing import RequestPublisher
from task_manager_mqtt.fleet.receiving import FleetReceiver, HeldCallback
from task_manager_mqtt.fleet.transport import BufferedClient, ClientLoop
from task_manager_mqtt.fleet_types import (
    TIMEOUT_SEC,
    Document,
    FleetError,
    FleetTask,
    Reply,
    RobotView,
    ScheduleFields,
    StartOptions,
    outcome,
    schedule_document,
)
from task_manager_mqtt.settings import DEFAULT_PREFIX, Broker, Tls
from task_manager_mqtt.topics import ANY_ROBOT, FOLLOWED, TopicName, Topics

LOG = logging.getLogger('task_manager_mqtt.fleet')
RequestCheck = Callable[[str, str, Document], None]
"""check_request(robot_id, op, fields): raises FleetError to refuse a request before it is sent."""
SESSION_EXPIRY_SEC = 24 * 3600
RECONNECT_MAX_SEC = 2
FINAL_STATUSES = ('DONE', 'ERROR', 'CANCELED')
KEEPALIVE_SEC = 60
CLOSE_TIMEOUT_SEC = 10.0
"""How long close() waits for the MQTT thread (a connection being made, say)."""


class FleetClient:
    """Use it as a context manager, or call `connect()` then `close()`."""

    def __init__(
        self,
        broker_url: str,
        *,
        prefix: str = DEFAULT_PREFIX,
        client_id: str = '',
        source: str = 'CLOUD',
        events: bool = False,
        ca_file: str = '',
        password: str = '',
        hold_results: bool = False,
        receive_maximum: int = 0,
        max_message_bytes: int = 0,
        check_request: RequestCheck | None = None,
    ) -> None:
        """`client_id`: a stable one keeps this client's session (and the results sent while
        it is away) on the broker for SESSION_EXPIRY_SEC; empty: a new id, no session kept.
        A broker that ties client ids to accounts (mosquitto's `use_username_as_clientid`,
        as `make fleet`'s does) uses the user name instead: one connection per account.
        `events`: also follow every task event of every robot (see `on_event`).

        `ca_file`: with an mqtts:// URL, the certificate authorities to trust (else the
        system's). `password`: the account's, if the URL has none (read from a file, say: a
        password on a command line is visible to every user of the machine in `ps`).

        `hold_results`: a result message is acknowledged to the broker only when the
        `acknowledge` of `on_held_result` is called (see there); every other message at once.
        `receive_maximum`: the most QoS 1 messages the broker sends before their
        acknowledgements (MQTT 5's Receive Maximum; 0: the broker's choice).
        `max_message_bytes`: a robot's message larger than this is not read, but reported to
        `on_bad_message` (0: any size the broker passes on).

        `check_request(robot_id, op, fields)`: called before each request is sent; a FleetError
        it raises refuses the request (raised by the call that would have sent it).
        """
        broker = Broker.from_url(broker_url, Tls(ca_file=ca_file) if ca_file else None)
        self.broker = replace(broker, password=password) if password else broker
        self.prefix = prefix
        self.source = source
        self._receive_maximum = receive_maximum
        self._check_request = check_request
        self._followed = (*FOLLOWED, TopicName.EVENT) if events else FOLLOWED
        self._subscribed = threading.Event()
        self._request_numbers = itertools.count(1)
        self._session_sec = SESSION_EXPIRY_SEC if client_id else 0
        client = new_client(
            client_id or f'fleet_{uuid.uuid4().hex[:12]}',
            self.broker,
            RECONNECT_MAX_SEC,
            1000,
            manual_ack=hold_results,
            client_class=BufferedClient,
        )
        assert isinstance(client, BufferedClient)
        self._mqtt = client
        self._loop = ClientLoop(self._mqtt, RECONNECT_MIN_SEC, RECONNECT_MAX_SEC)
        self._hold_results = hold_results
        self._receiver = FleetReceiver(
            prefix,
            self._mqtt.ack,
            hold_results=hold_results,
            max_message_bytes=max_message_bytes,
        )
        self._publisher = RequestPublisher(self._mqtt, self._receiver)
        self.robots: dict[str, RobotView] = self._receiver.robots
        """What is known of each robot, by id (kept up to date as their documents come)."""
        self._all = Topics(prefix, ANY_ROBOT)
        self._mqtt.on_connect = self._on_connect
        self._mqtt.on_subscribe = lambda *_: self._subscribed.set()
        self._mqtt.on_message = self._on_message
        self._mqtt.on_received = self._on_received
        self._mqtt.on_publish = self._publisher.on_publish

    def __enter__(self) -> 'FleetClient':
        self.connect()
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def connect(self, timeout_sec: float = TIMEOUT_SEC) -> None:
        """Connect and subscribe (reconnecting by itself afterwards); FleetError if not in time."""
        connect(
            self._mqtt,
            self.broker,
            KEEPALIVE_SEC,
            self._session_sec,
            self._receive_maximum,
            start_loop=False,
        )
        self._loop.start()
        if not self._subscribed.wait(timeout_sec):
            self.close()
            raise FleetError(f'no connection to the broker at {self.broker.url} in {timeout_sec} s')

    def close(self) -> None:
        """Disconnect (the broker keeps the session of a client id given)."""
        self._loop.stop(CLOSE_TIMEOUT_SEC)

    # ---- requests -----------------------------------------------------------------------------

    def start_task(
        self,
        robot_id: str,
        task_name: str,
        task_data: Document | None = None,
        *,
        task_id: str = '',
        source: str = '',
        **options: Unpack[StartOptions],
    ) -> FleetTask:
        """Start a task on a robot; its reply and result come to the FleetTask.

        `options`: the start's priority, on_conflict, timeout_sec, queue_timeout_sec and
        feedback_timeout_sec (left out: the robot's declaration of the task).
        """
        fields = {'task_name': task_name, 'task_data': task_data or {}, **options}
        return self._start(robot_id, 'start_task', fields, task_id, source)

    def start_mission(
        self,
        robot_id: str,
        subtasks: list[Document],
        *,
        task_id: str = '',
        source: str = '',
        **options: Unpack[StartOptions],
    ) -> FleetTask:
        """Start a mission: `subtasks` as StartMission's (task_name, task_data, allow_skipping);
        `options` as start_task's, of the mission as one unit."""
        fields = {'subtasks': subtasks, **options}
        return self._start(robot_id, 'start_mission', fields, task_id, source)

    def cancel(
        self, robot_id: str, task_ids: list[str], timeout_sec: float = TIMEOUT_SEC
    ) -> Document:
        """system/cancel_task on the robot; its ended Task document."""
        return self._answer(robot_id, 'cancel', timeout_sec, task_ids=task_ids)['task']

    def stop(self, robot_id: str, timeout_sec: float = TIMEOUT_SEC) -> Document:
        """system/stop on the robot; its ended Task document."""
        return self._answer(robot_id, 'stop', timeout_sec)['task']

    def reprioritize(
        self, robot_id: str, task_ids: list[str], priority: int, timeout_sec: float = TIMEOUT_SEC
    ) -> Document:
        """system/reprioritize on the robot; its ended Task document (`successful_changes`,
        `errors` in its result)."""
        fields = {'task_ids': task_ids, 'priority': priority}
        return self._answer(robot_id, 'reprioritize', timeout_sec, **fields)['task']

    def why(self, robot_id: str, task_id: str, timeout_sec: float = TIMEOUT_SEC) -> list[Document]:
        """Every decision the robot's Task Manager took about a task (Decision documents,
        oldest first); FleetError `unknown_task_id` when it knows no such task."""
        return self._answer(robot_id, 'why', timeout_sec, task_id=task_id)['decisions']

    def history(
        self, robot_id: str, timeout_sec: float = TIMEOUT_SEC, **filters: Any
    ) -> list[Document]:
        """Ended tasks from the robot's durable history (HistoryQuery's filters)."""
        return self._answer(robot_id, 'history', timeout_sec, **filters)['tasks']

    def pause(
        self, robot_id: str, task_ids: list[str], timeout_sec: float = TIMEOUT_SEC
    ) -> Document:
        """system/pause on the robot (a mission between its subtasks, a task declared `pause:
        restart` at once); its Paused document: the ids `paused` (one already paused counts),
        `errors` (why not the others), the system `task`, ended."""
        return self._answer(robot_id, 'pause', timeout_sec, task_ids=task_ids)['paused']

    def resume(
        self, robot_id: str, task_ids: list[str], timeout_sec: float = TIMEOUT_SEC
    ) -> Document:
        """system/resume on the robot; its Resumed document: the ids `resumed`, `errors` (why
        not the others, e.g. not paused), the system `task`, ended."""
        return self._answer(robot_id, 'resume', timeout_sec, task_ids=task_ids)['resumed']

    def schedule_task(
        self,
        robot_id: str,
        task_name: str,
        task_data: Document | None = None,
        *,
        reply_timeout_sec: float = TIMEOUT_SEC,
        **fields: Unpack[ScheduleFields],
    ) -> Document:
        """system/schedule of a task on the robot; its Scheduled document: `scheduled`, the
        `schedule_id`, its `next_run`, and `message` (when it runs, or why the robot's Task
        Manager refused it: an unknown task, bad task_data or cron, an id taken, ...).

        `fields`: exactly one of `at`, `delay_sec`, `period_sec`, `cron`, and the rest of
        ScheduleTask's (schedule_id, time_zone, window_start, window_end, max_runs, overlap,
        misfire_grace_sec), with start_task's options for each run (`timeout_sec` being each
        run's; `reply_timeout_sec` is the wait for the robot's reply). A request the bridge
        cannot take (two whens, a field misspelt, ...) is FleetError `invalid_request`.
        """
        what = {'task_name': task_name, 'task_data': task_data or {}}
        document = {**what, **schedule_document(fields)}
        return self._answer(robot_id, 'schedule', reply_timeout_sec, **document)['scheduled']

    def schedule_mission(
        self,
        robot_id: str,
        subtasks: list[Document],
        *,
        reply_timeout_sec: float = TIMEOUT_SEC,
        **fields: Unpack[ScheduleFields],
    ) -> Document:
        """system/schedule of a mission (`subtasks` as start_mission's), as schedule_task;
        a subtask's task_id only in a schedule that runs once (each run makes its own)."""
        document = {'subtasks': subtasks, **schedule_document(fields)}
        return self._answer(robot_id, 'schedule', reply_timeout_sec, **document)['scheduled']

    def unschedule(
        self, robot_id: str, schedule_id: str, timeout_sec: float = TIMEOUT_SEC
    ) -> Document:
        """system/unschedule of a schedule on the robot (its runs already started go on); its
        ended Task document. FleetError `unknown_schedule_id` when there is no such schedule."""
        return self._answer(robot_id, 'unschedule', timeout_sec, schedule_id=schedule_id)['task']

    def enable_schedules(
        self,
        robot_id: str,
        schedule_ids: list[str],
        enabled: bool,
        timeout_sec: float = TIMEOUT_SEC,
    ) -> list[Document]:
        """Disable schedules on the robot (no runs; their counts kept) or enable them again
        (from their next due time after now); the Schedule documents changed, as they are then.
        FleetError `unknown_schedule_id` (and none changed) when one is no schedule."""
        fields = {'schedule_ids': schedule_ids, 'enabled': enabled}
        return self._answer(robot_id, 'enable_schedules', timeout_sec, **fields)['schedules']

    def schedules(
        self,
        robot_id: str,
        schedule_ids: list[str] | None = None,
        timeout_sec: float = TIMEOUT_SEC,
    ) -> list[Document]:
        """The robot's schedules (Schedule documents: when each runs, its next run, its last
        run's status, its counts), every one or those of `schedule_ids` that exist."""
        fields = {'schedule_ids': schedule_ids or []}
        return self._answer(robot_id, 'schedules', timeout_sec, **fields)['schedules']

    def confirm(
        self,
        robot_id: str,
        task_id: str,
        *,
        reject: bool = False,
        comment: str = '',
        source: str = '',
        timeout_sec: float = TIMEOUT_SEC,
    ) -> Document:
        """Answer a waiting system/confirm on the robot: confirmed, it ends DONE; rejected,
        ERROR `rejected`. Its result's `by` is the bridge's source, followed by the name
        `source` gives (`CLOUD:alice`), as a start's. The Confirmed document; FleetError
        `unknown_task_id`, or `not_waiting` for a task that is no waiting one."""
        fields = {'task_id': task_id, 'reject': reject, 'comment': comment}
        if source:
            fields['source'] = source
        return self._answer(robot_id, 'confirm', timeout_sec, **fields)['confirmed']

    def request(
        self, robot_id: str, op: str, *, request_id: str = '', **fields: Any
    ) -> Future[Document]:
        """Send any request; the future completes with the robot's Reply document, or fails
        with FleetError if the broker refuses it or takes no message that large. A FleetError
        of `check_request` is raised here, and nothing is sent."""
        if self._check_request is not None:
            self._check_request(robot_id, op, fields)
        request_id = request_id or f'{uuid.uuid4().hex[:12]}-{next(self._request_numbers)}'
        reply: Future[Document] = Future()
        document = {'request_id': request_id, 'op': op, **fields}
        topic = Topics(self.prefix, robot_id).request
        self._publisher.publish(topic, request_id, json.dumps(document).encode(), reply)
        return reply

    def _answer(self, robot_id: str, op: str, wait_sec: float, /, **fields: Any) -> Reply:
        """The robot's reply to a request (FleetError if it is an error reply); `fields` may
        hold a `timeout_sec` of their own (a schedule's runs')."""
        reply = outcome(self.request(robot_id, op, **fields), wait_sec, f'reply of {robot_id}')
        return cast(Reply, reply)

    def _start(
        self, robot_id: str, op: str, fields: Document, task_id: str, source: str
    ) -> FleetTask:
        task_id = task_id or str(uuid.uuid4())
        result: Future[Document] = Future()
        self._receiver.expect_result(robot_id, task_id, result)
        try:
            reply = self.request(
                robot_id, op, task_id=task_id, source=source or self.source, **fields
            )
        except FleetError:  # refused by check_request
            self._receiver.take_result(robot_id, task_id)
            raise
        reply.add_done_callback(lambda done: self._on_start_reply(robot_id, task_id, done))
        return FleetTask(robot_id, task_id, reply, result)

    def _on_start_reply(self, robot_id: str, task_id: str, reply: Future[Document]) -> None:
        """A refused start fails its result; a duplicate of an ended task has it already."""
        if (failure := reply.exception()) is not None:  # not sent, or refused by the broker
            result = self._receiver.take_result(robot_id, task_id)
            if result is not None and not result.done():
                result.set_exception(failure)
            return
        document = reply.result()
        known = document.get('task') or {}
        ended = document.get('duplicate') and known.get('status') in FINAL_STATUSES
        if document.get('ok') and not ended:
            return
        result = self._receiver.take_result(robot_id, task_id)
        if result is None or result.done():
            return
        if ended:
            result.set_result(known)
        else:
            error = document.get('error') or {}
            result.set_exception(FleetError(error.get('message', 'refused'), error.get('code', '')))

    # ---- following the fleet ------------------------------------------------------------------

    def on_result(self, callback: Callable[[str, Document], None]) -> None:
        """`callback(robot_id, task)` for every result of every robot (once per sequence)."""
        self._receiver.result_callbacks.append(callback)

    def on_event(self, callback: Callable[[str, Document], None]) -> None:
        """`callback(robot_id, event)` for every TaskEvent document (with `events=True`)."""
        self._receiver.event_callbacks.append(callback)

    def on_dead_letter(self, callback: Callable[[str, Document], None]) -> None:
        """`callback(robot_id, dead_letter)` for every request message a robot could not
        answer, having no usable request_id (a DeadLetter document: the reason, an excerpt)."""
        self._receiver.dead_letter_callbacks.append(callback)

    def on_held_result(self, callback: HeldCallback) -> None:
        """With `hold_results`: `callback(robot_id, task, acknowledge)` for every delivery of
        every result, again after a reconnection too (the callback tells them apart by robot
        and sequence); the broker keeps the result until `acknowledge()` is called (from any
        thread), once it is kept. The callback must not wait: it is on the MQTT thread."""
        self._receiver.held_callbacks.append(callback)

    def on_state(self, callback: Callable[[str, str, Document | None], None]) -> None:
        """`callback(robot_id, name, document)` for every retained state document as it comes
        (`name`: connection, tasks or active_tasks; None: the retained one was cleared)."""
        self._receiver.state_callbacks.append(callback)

    def on_bad_message(self, callback: Callable[[str, str, str], None]) -> None:
        """`callback(robot_id, name, why)` for every message of a robot that is not read (too
        large, not JSON, not an object); with one, this client logs none of them itself."""
        self._receiver.bad_message_callbacks.append(callback)

    def on_robot_change(self, callback: Callable[[RobotView], None]) -> None:
        """`callback(robot)` when a robot's connection, active or declared tasks change."""
        self._receiver.robot_callbacks.append(callback)

    def wait_for(
        self, condition: Callable[[dict[str, RobotView]], bool], timeout_sec: float = TIMEOUT_SEC
    ) -> bool:
        """Wait until `condition(robots)` holds (checked at each change); whether it did."""
        return self._receiver.wait_for(condition, timeout_sec)

    def wait_online(self, robot_ids: list[str], timeout_sec: float = TIMEOUT_SEC) -> bool:
        """Wait until these robots are ONLINE and reach their Task Manager."""

        def ready(robots: dict[str, RobotView]) -> bool:
            return all(
                (r := robots.get(i)) is not None
                and r.online
                and bool(r.connection and r.connection.get('task_manager_connected'))
                for i in robot_ids
            )

        return self.wait_for(ready, timeout_sec)

    # ---- on the MQTT client's thread ----------------------------------------------------------

    def _on_connect(
        self, client: mqtt.Client, _: Any, __: Any, reason: ReasonCode, properties: Any
    ) -> None:
        if reason.is_failure:
            LOG.warning('the broker refused the connection: %s', reason)
            return
        self._publisher.largest_payload = largest_payload(properties, None)
        client.subscribe([(self._all.topic(name), 1) for name in self._followed])

    def _on_message(self, _: mqtt.Client, __: Any, message: mqtt.MQTTMessage) -> None:
        """A message paho read itself (see BufferedClient); one whose topic is not UTF-8 (no
        broker should pass it on) is ignored."""
        try:
            topic = message.topic
        except UnicodeDecodeError:
            LOG.error('a message on a topic that is not UTF-8 was ignored')
            if self._hold_results:
                self._mqtt.ack(message.mid, message.qos)
            return
        self._on_received(topic, bytes(message.payload), message.mid, message.qos)

    def _on_received(self, topic: str, payload: bytes, mid: int, qos: int) -> None:
        """The callbacks' boundary: an exception here would end the MQTT thread's round."""
        held = False
        try:
            held = self._dispatch(topic, payload, mid, qos)
        except Exception as error:  # a robot's bad document, or a user's callback: logged
            LOG.error('%s: %s: %s', topic, type(error).__name__, error)
        finally:
            if self._hold_results and not held:
                self._mqtt.ack(mid, qos)

    def _dispatch(self, topic: str, payload: bytes, mid: int = 0, qos: int = 0) -> bool:
        """Pass the message on; whether a held result's acknowledgement was handed over."""
        return self._receiver.receive(topic, payload, mid, qos)
