"""/task_manager/task_events: one TaskEvent per change of a task, feedback rate-limited; and
/task_manager/task_event_batches: the same events in the same order, those of one executor turn
in one TaskEventArray (at most EVENTS_MAX of them, EVENT_BATCH_MAX_BYTES of their text), which
the client and the gateways follow. Each topic is written only while someone subscribes to it.

Every task gets RECEIVED, then STARTED (unless it ends before starting), FEEDBACK updates
(PAUSED and RESUMED for each pause), and ENDED, in that order, each with the task's whole
state. Feedback goes out at most
`feedback_rate_hz` times a second per task (see core/feedback_rate.py); a feedback held
back when the task ends goes out just before its ENDED event. Feedback recorded before the
task is IN_PROGRESS (a system task's first, made as it starts) goes out just after STARTED.
"""

import time
from typing import Any

from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.timer import Timer
from task_manager_msgs.msg import TaskEvent, TaskEventArray

from task_manager.core.admission.decisions import DecisionKind
from task_manager.core.bounds import EVENT_BATCH_MAX_BYTES
from task_manager.core.event_batch import EventBatch
from task_manager.core.feedback_rate import FeedbackAction, FeedbackGate
from task_manager.core.names import TASK_EVENT_BATCHES_TOPIC, TASK_EVENTS_TOPIC
from task_manager.core.task import TaskRecord
from task_manager.messages.task_messages import task_state_fields
from task_manager.rclpy_tools import qos
from task_manager.rclpy_tools.cleanup import destroy_timer
from task_manager.ros.parking_executor import spawn_after_turn
from task_manager.ros.recording.event_batch_wire import (
    EncodedEvent,
    EventBatchEncoding,
    encode_event,
    event_batch_encoding,
    event_message,
)

_ENDING_DECISIONS = (DecisionKind.REFUSED, DecisionKind.PREEMPTED, DecisionKind.TIMEOUT)


def end_reason(record: TaskRecord) -> str:
    """Why the Task Manager ended the task, when it did (refused, pre-empted, timed out)."""
    if record.decisions and record.decisions[-1].decision in _ENDING_DECISIONS:
        return record.decisions[-1].reason
    return ''


class TaskEventStream:
    """Publishes the events of every task; does nothing when switched off."""

    def __init__(self, node: Node, enabled: bool, feedback_rate_hz: float) -> None:
        self.enabled = enabled
        self._node = node
        self._min_interval_sec = 1.0 / feedback_rate_hz
        self._publisher: Publisher[TaskEvent] | None = None
        self._batches: Publisher[TaskEventArray] | None = None
        # the events of this turn not published on the batch topic yet: encoded, where the
        # middleware writes what event_batch_wire does (checked in `open`), else messages
        self._encoding: EventBatchEncoding | None = None
        self._batch = EventBatch[EncodedEvent | TaskEvent](
            TaskEventArray.EVENTS_MAX, EVENT_BATCH_MAX_BYTES
        )
        self._flush_after_turn = False
        # key: task id, value: its feedback rate limit, while the task is active
        self._gates: dict[str, FeedbackGate] = {}
        # key: task id, value: the one-shot timer that sends its held feedback
        self._timers: dict[str, Timer] = {}
        # ids of the tasks with feedback recorded before they started: sent after STARTED
        self._feedback_before_start: set[str] = set()

    def open(self) -> None:
        """Create the publisher (when the node starts serving)."""
        if self.enabled:
            self._encoding = event_batch_encoding()
            self._publisher = self._node.create_publisher(
                TaskEvent,
                TASK_EVENTS_TOPIC,
                qos.TASK_EVENTS,
                event_callbacks=qos.without_qos_events(),
            )
            self._batches = self._node.create_publisher(
                TaskEventArray,
                TASK_EVENT_BATCHES_TOPIC,
                qos.TASK_EVENTS,
                event_callbacks=qos.without_qos_events(),
            )

    def received(self, record: TaskRecord) -> None:
        if self._publisher is None:
            return
        record.feedback_listeners.append(self.feedback)
        self._publish(TaskEvent.RECEIVED, record)

    def started(self, record: TaskRecord, reason: str = '') -> None:
        if self._publisher is not None:
            self._publish(TaskEvent.STARTED, record, reason)
            if record.task_id in self._feedback_before_start:
                self._feedback_before_start.discard(record.task_id)
                self.feedback(record)

    def queued(self, record: TaskRecord, reason: str) -> None:
        if self._publisher is not None:
            self._publish(TaskEvent.QUEUED, record, reason)

    def decided(self, record: TaskRecord, reason: str) -> None:
        """A decision that changes no status: a priority changed, a retry planned."""
        if self._publisher is not None:
            self._publish(TaskEvent.DECIDED, record, reason)

    def paused(self, record: TaskRecord) -> None:
        if self._publisher is not None:
            self._release(record)  # the feedback from before the pause comes first
            self._publish(TaskEvent.PAUSED, record)

    def resumed(self, record: TaskRecord) -> None:
        if self._publisher is not None:
            self._publish(TaskEvent.RESUMED, record)

    def feedback(self, record: TaskRecord) -> None:
        if record.is_final:  # a late update after the end is not an event
            return
        if not record.status.is_started:  # RECEIVED or QUEUED: sent after its STARTED
            self._feedback_before_start.add(record.task_id)
            return
        gate = self._gates.get(record.task_id)
        if gate is None:
            gate = self._gates[record.task_id] = FeedbackGate(self._min_interval_sec)
        now = time.monotonic()
        action = gate.offer(now)
        if action is FeedbackAction.SEND:
            self._publish(TaskEvent.FEEDBACK, record)
        elif action is FeedbackAction.HOLD:
            self._timers[record.task_id] = self._node.create_timer(
                gate.delay_until_slot(now), lambda: self._release(record)
            )

    def ended(self, record: TaskRecord) -> None:
        if self._publisher is None:
            return
        self._release(record)
        self._gates.pop(record.task_id, None)
        self._feedback_before_start.discard(record.task_id)
        self._publish(TaskEvent.ENDED, record, end_reason(record))

    def _release(self, record: TaskRecord) -> None:
        """Send the held feedback of `record`, if any (its slot has come, or it ends)."""
        timer = self._timers.pop(record.task_id, None)
        if timer is not None:
            destroy_timer(self._node, timer)
        gate = self._gates.get(record.task_id)
        if gate is not None and gate.release(time.monotonic()):
            self._publish(TaskEvent.FEEDBACK, record)

    def flush(self) -> None:
        """Publish the batch of events gathered so far (at the end of a turn, and before the
        results of the tasks whose ENDED it holds)."""
        self._send_batch(self._batch.take())

    def _publish(self, event: str, record: TaskRecord, reason: str = '') -> None:
        assert self._publisher is not None and self._batches is not None
        one_by_one = self._publisher.get_subscription_count() > 0
        batched = self._batches.get_subscription_count() > 0
        if not (one_by_one or batched):
            return  # nobody listens: building the message is the larger part of the cost
        now, fields = time.time(), task_state_fields(record)
        if one_by_one:
            self._publisher.publish(event_message(event, now, fields, reason))
        if batched:
            encoded: EncodedEvent | TaskEvent = (
                encode_event(event, now, fields, reason)
                if self._encoding is not None
                else event_message(event, now, fields, reason)
            )
            self._add_to_batch(encoded, _text_size(fields))

    def _add_to_batch(self, event: 'EncodedEvent | TaskEvent', size: int) -> None:
        self._send_batch(self._batch.add(event, size))
        if not self._flush_after_turn:
            self._flush_after_turn = True
            spawn_after_turn(self._node, self._end_of_turn())

    async def _end_of_turn(self) -> None:
        self._flush_after_turn = False
        self.flush()

    def _send_batch(self, events: 'list[EncodedEvent | TaskEvent]') -> None:
        if not events or self._batches is None:
            return
        if self._encoding is not None:
            self._batches.publish(self._encoding.array(events))
        else:
            self._batches.publish(TaskEventArray(events=events))


def _text_size(fields: dict[str, Any]) -> int:
    """About what an event weighs on the wire: its text fields, in characters."""
    return sum(len(fields[name]) for name in ('feedback', 'task_result', 'decisions', 'pauses'))
