"""One robot's Task Manager on an MQTT broker: requests in, replies, results and state out.

Three threads meet here, none parked per task: the MQTT client's network thread (paho), the
Task Manager client's executor thread, and one worker that does everything else in order,
taking jobs from a queue: requests (which call the Task Manager), results, the retained
state. The callbacks of the two others only queue jobs, so they never wait.

Results go out in the order of the history's sequence numbers, each at QoS 1: live from the
ENDED events while the broker is there, and from the node's durable history for whatever
was missed (the broker away, the bridge restarted, an event lost). See ResultOutbox.

Each request message gets one reply, or one dead letter when it has no request_id to address
a reply to, and then its acknowledgement, whatever it holds (see decoding.py).
"""

import contextlib
import logging
import queue
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from functools import partial
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.reasoncodes import ReasonCode
from paho.mqtt.subscribeoptions import SubscribeOptions

from task_manager.client import TaskEvent, TaskEventKind, TaskManagerClient, TaskState
from task_manager.core.errors import TaskManagerUnavailable
from task_manager.core.text.json_text import compact_json
from task_manager.gateway.documents import declared_json, event_json, iso, task_json
from task_manager.protocol.errors import RefusalCode
from task_manager_mqtt.active_list import ActiveList
from task_manager_mqtt.connection import (
    RECONNECT_MIN_SEC,
    connect,
    largest_payload,
    new_client,
)
from task_manager_mqtt.decoding import refusal
from task_manager_mqtt.outbox import ResultOutbox
from task_manager_mqtt.outgoing import Outgoing
from task_manager_mqtt.requests import RequestHandler
from task_manager_mqtt.settings import BridgeSettings, Broker
from task_manager_mqtt.topics import Topics

LOG = logging.getLogger('task_manager_mqtt')
MAX_IN_FLIGHT = 200
"""QoS 1 messages sent before their acknowledgements (paho's default, 20, slows a catch-up)."""
SESSION_EXPIRY_SEC = 7 * 24 * 3600
"""How long the broker keeps the bridge's subscription and the requests sent meanwhile."""
OFFLINE_TIMEOUT_SEC = 2.0
QUIET_CHECK_SEC = 1.0
"""After the last task ended, when to look in the history for results not sent."""
REQUESTS_SUBSCRIPTION = SubscribeOptions(
    qos=1, retainAsPublished=True, retainHandling=SubscribeOptions.RETAIN_DO_NOT_SEND
)
"""A retained request would run again at every (re)subscription: the broker hands over none
that it stored (retain handling 2), and one published with the retain flag comes with it, to
be refused (retain as published)."""
EXCERPT_BYTES = 200
"""Of a dead letter's payload, shown in its document."""
DEAD_LETTER_LOG_SEC = 10.0
# MQTT 5 reason codes, and MQTT 3.1.1 return codes, of a connection refused for its credentials
CREDENTIALS_REFUSED = ('Bad user name or password', 'Not authorized')


class Bridge:
    def __init__(
        self,
        settings: BridgeSettings,
        client: TaskManagerClient,
        on_failure: Callable[[], None] = lambda: None,
    ) -> None:
        """`on_failure` is called (on the MQTT thread) if the bridge cannot go on."""
        self.settings = settings
        self.topics = Topics(settings.prefix, settings.robot_id)
        self.client = client
        self.outbox = ResultOutbox(
            settings.acked_file, lambda: self._jobs.put(self.outbox.write_acked)
        )
        self.requests = RequestHandler(client, settings.source, settings.max_payload_bytes)
        self.failed = threading.Event()
        """Set when the bridge cannot go on (the broker refused its credentials)."""
        self.failure = ''
        self._on_failure = on_failure
        self._jobs: queue.SimpleQueue[Callable[[], None] | None] = queue.SimpleQueue()
        self._worker = threading.Thread(target=self._work, name='bridge-worker', daemon=True)
        self._stopping = False
        self._largest_payload: int = settings.max_payload_bytes
        """Of a message sent: the bridge's limit, or the broker's if smaller."""
        self._outgoing = Outgoing()
        self._reconnecting = False
        # the rest belongs to the worker
        self._broker_up = False
        self._declared: dict[str, Any] | None = None
        self._active = ActiveList()
        self._active_queued = False
        self._connection_queued = False
        self._dead_letters = 0
        """Request messages put on dead_letter since the start."""
        self._dead_letter_logged = -DEAD_LETTER_LOG_SEC
        self._check_due: float | None = None
        self._node_ready = False
        """The worker has read the node's state since it last connected."""
        self.mqtt = self._mqtt_client(settings.broker)
        self._unsubscribe = [
            client.on_task_event(lambda event: self._jobs.put(partial(self._on_event, event))),
            client.on_events_lost(lambda _: self._jobs.put(self._on_events_lost)),
            client.on_connection_change(
                lambda up: self._jobs.put(partial(self._on_node_change, up))
            ),
        ]

    # ---- lifecycle ---------------------------------------------------------------------------

    def start(self) -> None:
        self._worker.start()
        self._jobs.put(partial(self._on_node_change, self.client.connected))
        broker = self.settings.broker
        LOG.info('connecting to the broker at %s as robot %r', broker.url, self.settings.robot_id)
        connect(self.mqtt, broker, self.settings.keepalive_sec, SESSION_EXPIRY_SEC)

    def stop(self) -> None:
        """OFFLINE (retained), a clean disconnection (so no last will), the worker ended."""
        self._stopping = True
        if self.mqtt.is_connected():
            info = self._publish(self.topics.connection, self._connection('OFFLINE'), 1, True)
            if info is not None:
                info.wait_for_publish(OFFLINE_TIMEOUT_SEC)
        self.mqtt.disconnect()
        self.mqtt.loop_stop()
        for unsubscribe in self._unsubscribe:
            unsubscribe()
        self._jobs.put(None)
        self._worker.join()
        try:  # what was acknowledged since the worker's last write
            self.outbox.write_acked()
        except OSError as error:
            LOG.error('cannot write %s: %s', self.settings.acked_file, error)

    def _mqtt_client(self, broker: Broker) -> mqtt.Client:
        client_id = f'task_manager_{self.settings.robot_id}'
        # a request is acknowledged once answered: one the bridge received but never answered
        # (it was killed) is delivered again when it reconnects
        client = new_client(
            client_id, broker, self.settings.reconnect_max_sec, MAX_IN_FLIGHT, manual_ack=True
        )
        will = self._connection('CONNECTIONBROKEN', task_manager_connected=False)
        client.will_set(self.topics.connection, compact_json(will), qos=1, retain=True)
        client.on_connect = self._on_connect
        client.on_connect_fail = self._on_connect_fail
        client.on_disconnect = self._on_disconnect
        client.on_message = self._on_message
        client.on_publish = self._on_publish
        return client

    # ---- on the MQTT client's thread: queue, never wait -------------------------------------

    def _on_connect(
        self, client: mqtt.Client, _: Any, __: Any, reason: ReasonCode, properties: Any
    ) -> None:
        if reason.is_failure:
            if str(reason) in CREDENTIALS_REFUSED:
                self.failure = (
                    f'the broker at {self.settings.broker.url} refused the credentials: '
                    f'{reason} (check the user name and password)'
                )
                self.failed.set()
                self._on_failure()
            elif not self._reconnecting:
                LOG.warning('the broker refused the connection: %s; retrying', reason)
                self._reconnecting = True
            return
        LOG.info(
            'connected to the broker at %s: topics %s/',
            self.settings.broker.url,
            self.topics.topic('').rstrip('/'),
        )
        self._reconnecting = False
        self._largest_payload = largest_payload(properties, self.settings.max_payload_bytes)
        client.subscribe(self.topics.request, options=REQUESTS_SUBSCRIPTION)
        self._jobs.put(self._on_broker_up)

    def _on_connect_fail(self, _: mqtt.Client, __: Any) -> None:
        if not self._reconnecting:  # once per series of attempts
            LOG.warning(
                'cannot reach the broker at %s; retrying every %d to %d s until it answers',
                self.settings.broker.url,
                RECONNECT_MIN_SEC,
                self.settings.reconnect_max_sec,
            )
            self._reconnecting = True

    def _on_disconnect(
        self, _: mqtt.Client, __: Any, ___: Any, reason: ReasonCode, ____: Any
    ) -> None:
        self._jobs.put(self._on_broker_down)
        if not self._stopping and not self.failed.is_set() and not self._reconnecting:
            LOG.warning('lost the broker (%s); reconnecting', reason)
            self._reconnecting = True

    def _on_message(self, _: mqtt.Client, __: Any, message: mqtt.MQTTMessage) -> None:
        payload, retained = bytes(message.payload), bool(message.retain)
        self._jobs.put(partial(self._answer, payload, message.mid, message.qos, retained))

    def _on_publish(self, _: mqtt.Client, __: Any, mid: int, reason: ReasonCode, ___: Any) -> None:
        if reason.is_failure:
            LOG.error('the broker refused message %d: %s', mid, reason)
        self.outbox.on_ack(mid)

    # ---- the worker ---------------------------------------------------------------------------

    def _work(self) -> None:
        while True:
            try:
                job = self._jobs.get(timeout=self._until_check())
            except queue.Empty:  # quiet since the last task ended: the check is due
                self._check_due = None
                job = self._catch_up
            if job is None:
                return
            try:
                job()
            except Exception as error:  # one line; the bridge goes on
                LOG.error('%s failed: %s: %s', _name(job), type(error).__name__, error)

    def _check_soon(self) -> None:
        """Look for results not sent once no task has ended for QUIET_CHECK_SEC.

        A safety net: an ENDED event that never arrives (or a history read that failed)
        would otherwise leave its result unsent until the next task ends.
        """
        self._check_due = time.monotonic() + QUIET_CHECK_SEC

    def _until_check(self) -> float | None:
        return None if self._check_due is None else max(self._check_due - time.monotonic(), 0.0)

    def _on_broker_up(self) -> None:
        self._broker_up = True
        self.outbox.resend_unacked()
        if self._declared is not None:
            self._publish(self.topics.tasks, self._declared, 1, True)
        self._publish_active()
        self._publish_connection()  # last: once ONLINE is seen, the state above is there
        self._catch_up()

    def _on_broker_down(self) -> None:
        self._broker_up = False

    def _on_node_change(self, connected: bool) -> None:
        LOG.info('the Task Manager is %s', 'reachable' if connected else 'not reachable')
        self._node_ready = False
        if connected:
            try:
                self._read_node_state()
                self._node_ready = True
            except TaskManagerUnavailable as error:
                LOG.warning('cannot read the Task Manager state: %s', error)
        self._publish_connection()  # after the node's state, as on a broker connection
        if self._node_ready:
            self._catch_up()

    def _read_node_state(self) -> None:
        now = iso(datetime.now(UTC))
        tasks = [declared_json(entry) for entry in self.client.declared_tasks()]
        self._declared = {'timestamp': now, 'tasks': tasks}
        self._publish(self.topics.tasks, self._declared, 1, True)
        self._read_active()
        self._publish_active()
        self._set_start_point()

    def _set_start_point(self) -> None:
        """From which sequence on results are sent: a first start sends none from before."""
        newest = self.client.history(limit=1)
        newest_sequence = newest[0].sequence if newest else 0
        if not self.outbox.known:
            LOG.info(
                'first start: the results after sequence %d are sent (none from before)',
                newest_sequence,
            )
            self.outbox.start_at(newest_sequence, newest[0].task_id if newest else '')
        elif newest_sequence < self.outbox.acked:
            LOG.warning(
                'the history ends at sequence %d, before the last acknowledged (%d): a new '
                'history; sending all of it',
                newest_sequence,
                self.outbox.acked,
            )
            self.outbox.start_at(0)
        elif self._another_task_at_acked():
            LOG.warning(
                'result %d of the history is not task %s, the last acknowledged: a new history; '
                'sending all of it',
                self.outbox.acked,
                self.outbox.acked_task_id,
            )
            self.outbox.start_at(0)

    def _another_task_at_acked(self) -> bool:
        """Whether the node's history numbers the last acknowledged result with another task:
        a new history that grew past it while the bridge was away (a history file never gives
        a number twice). Not known, so False, if the state file has no task id (written before
        it kept one) or retention deleted that result."""
        if not (self.outbox.acked and self.outbox.acked_task_id):
            return False
        found = self.client.history(
            after_sequence=self.outbox.acked - 1, limit=1, oldest_first=True
        )
        if not found or found[0].sequence != self.outbox.acked:
            return False  # retention deleted it: not known
        return found[0].task_id != self.outbox.acked_task_id

    def _on_event(self, event: TaskEvent) -> None:
        document = event_json(event)
        self._publish(self.topics.event, document, 0, False)
        if event.kind == TaskEventKind.ENDED:
            self._active.discard(event.task.task_id)
            self._send_result(event.task, document['task'])
        else:
            self._active.put(event.task.task_id, document['task'])
        self._queue_active()

    def _read_active(self) -> None:
        """The active list as the node has it now."""
        self._active.replace(task_json(s) for s in self.client.task_states())

    def _on_events_lost(self) -> None:
        """Events went missing (the client fell behind the node; it logged how many): the
        active list is read again. A result among them is sent from the history by number."""
        try:
            self._read_active()
        except TaskManagerUnavailable as error:
            LOG.warning('cannot read the active tasks again after events went missing: %s', error)
            return
        self._queue_active()
        self._catch_up()

    def _answer(self, payload: bytes, message_id: int, qos: int, retained: bool) -> None:
        """One reply or one dead letter, then the acknowledgement, whatever the message holds
        (a message never acknowledged holds a place of the broker's in-flight window for good:
        20 of them and the bridge would receive nothing more)."""
        answered = False
        try:
            if not self.outbox.known and self.client.connected:
                self._set_start_point()  # before any task this request starts could end
        except TaskManagerUnavailable as error:
            LOG.warning('the Task Manager is not reachable: %s', error)
        try:
            answer = self.requests.answer(payload, retained)
            if answer.reply is not None:
                self._publish(self.topics.reply, answer.reply, 1, False)
            else:
                self._dead_letter(payload, retained, answer.dead_letter or {})
            answered = True
        except Exception as error:  # the callback's boundary: logged, and still answered
            LOG.error('a request message failed: %s: %s', type(error).__name__, error)
        finally:
            if not answered:
                detail = refusal(RefusalCode.INTERNAL_ERROR, 'the bridge failed to answer it')
                with contextlib.suppress(Exception):
                    self._dead_letter(payload, retained, detail)
            self.mqtt.ack(message_id, qos)

    def _dead_letter(self, payload: bytes, retained: bool, reason: dict[str, str]) -> None:
        """Publish a message that cannot be answered on dead_letter, counted."""
        self._dead_letters += 1
        document = {
            'robot_id': self.settings.robot_id,
            'timestamp': iso(datetime.now(UTC)),
            'error': reason,
            'payload_bytes': len(payload),
            'payload_excerpt': payload[:EXCERPT_BYTES].decode(errors='backslashreplace'),
            'retained': retained,
            'count': self._dead_letters,
        }
        self._publish(self.topics.dead_letter, document, 1, False)
        self._queue_connection()
        now = time.monotonic()
        if now >= self._dead_letter_logged + DEAD_LETTER_LOG_SEC:  # at most one line in 10 s
            self._dead_letter_logged = now
            LOG.warning(
                'a request without a usable request_id went to %s (%d so far): %s',
                self.topics.dead_letter,
                self._dead_letters,
                reason.get('message', '')[:200],
            )

    # ---- results ------------------------------------------------------------------------------

    def _send_result(self, state: TaskState, document: dict[str, Any]) -> None:
        """A live result: sent now if it is the next; a gap is filled from the history."""
        self._check_soon()
        if not self._broker_up or not self.outbox.known:
            return  # sent from the history once both are there
        sequence = state.sequence
        if sequence == 0:  # the node keeps no history: live only
            self._publish(self.topics.result, document, 1, False)
        elif self.outbox.is_next(sequence):
            self._publish_result(sequence, document)
        elif not self.outbox.is_sent(sequence):
            self._catch_up()

    def _catch_up(self) -> None:
        """Send, in order, every result of the history after the last one sent."""
        if not (self._broker_up and self.outbox.known and self.client.connected):
            return
        try:
            for state in self.client.ended_after(self.outbox.sent):
                self._publish_result(state.sequence, task_json(state))
                if not self._broker_up:
                    return
        except TaskManagerUnavailable as error:
            LOG.warning('cannot read the history to send the results missed: %s', error)

    def _publish_result(self, sequence: int, document: dict[str, Any]) -> None:
        self.outbox.before_send()
        info = self._publish(self.topics.result, document, 1, False)
        task_id = str(document.get('task_id', ''))
        if info is None:  # nothing of it fits in a message (logged): it is never sent
            self.outbox.skip(sequence, task_id)
        else:
            self.outbox.mark_sent(sequence, info.mid, task_id)

    # ---- retained state -----------------------------------------------------------------------

    def _queue_active(self) -> None:
        """Publish the active tasks once the jobs queued now are done (one message for many)."""
        if not self._active_queued:
            self._active_queued = True
            self._jobs.put(self._publish_active)

    def _publish_active(self) -> None:
        self._active_queued = False
        if self._broker_up:
            now = iso(datetime.now(UTC))
            document, payload = self._active.document(now), self._active.payload(now)
            self._publish(self.topics.active_tasks, document, 1, True, payload)

    def _queue_connection(self) -> None:
        """Publish the connection document once the jobs queued now are done."""
        if not self._connection_queued:
            self._connection_queued = True
            self._jobs.put(self._publish_connection)

    def _publish_connection(self) -> None:
        self._connection_queued = False
        if self._broker_up:
            self._publish(self.topics.connection, self._connection('ONLINE'), 1, True)

    def _connection(self, state: str, task_manager_connected: bool | None = None) -> dict[str, Any]:
        if task_manager_connected is None:
            task_manager_connected = self._node_ready and self.client.connected
        return {
            'robot_id': self.settings.robot_id,
            'connection_state': state,
            'timestamp': iso(datetime.now(UTC)),
            'task_manager_connected': task_manager_connected,
            'version': '1',
            'dead_letters': self._dead_letters,
        }

    def _publish(
        self,
        topic: str,
        document: dict[str, Any],
        qos: int,
        retain: bool,
        encoded: bytes | None = None,
    ) -> mqtt.MQTTMessageInfo | None:
        """Publish `document` (`encoded`: its JSON text, if made already), made to fit in a
        message (outgoing.py); None if nothing fits.

        Never a message over the limit: the broker would drop the connection, and the MQTT
        client would send that message again at every reconnection."""
        name = topic.rsplit('/', 1)[-1]
        payload = self._outgoing.fitted(name, document, self._largest_payload, encoded)
        if payload is None:
            return None
        return self.mqtt.publish(topic, payload, qos=qos, retain=retain)


def _name(job: Callable[[], None]) -> str:
    function = job.func if isinstance(job, partial) else job
    return getattr(function, '__name__', repr(function))
