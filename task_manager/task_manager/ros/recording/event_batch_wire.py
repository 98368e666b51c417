"""/task_manager/task_event_batches' messages (TaskEventArray) as the bytes the middleware sends,
each event encoded once, when it happens, from the task's fields.

Building a TaskEvent in Python (its TaskState's 17 fields, four Time messages) and rclpy's
conversion of the array to C field by field were a tenth of the node's time with the gateways
attached (docs/benchmarks.md). The layout is CDR's, as the middleware's serializer writes it:
the encapsulation header, the sequence's length, then each event's fields in order; a string
is its length with the terminating NUL, aligned to 4, its UTF-8 bytes and the NUL; the two
8-byte numbers (`sequence`, `paused_sec`) are aligned to 8 from the start of the data. An event
is kept as two parts: its head (`event` to `task_result`), whose alignments hold from any
offset aligned to 4, and its tail (`sequence` to `reason`), from any offset aligned to 8; the
array pads before each. `event_batch_encoding()` checks the layout once against rclpy's
serializer; a middleware that writes other bytes gets None, and the node publishes messages
as before.
"""

import functools
import struct
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

from rclpy.serialization import serialize_message
from task_manager_msgs.msg import TaskEvent, TaskEventArray

from task_manager.messages.task_messages import stamp, stamp_parts, task_state_of_fields
from task_manager.rclpy_tools.wire import written_as_serialized

_U32 = struct.Struct('<I')
_TIME = struct.Struct('<iI')
_SEQUENCE_AND_PAUSED = struct.Struct('<Qd')
_POSITION_PRIORITY_ATTEMPT = struct.Struct('<IiI')
_HEAD_STRINGS = ('task_id', 'task_name', 'source', 'task_status', 'error_code', 'mission_id')
_STAMPS = ('received', 'started', 'ended')


class EncodedEvent(NamedTuple):
    """One event's bytes: its head from an offset aligned to 4, its tail from one aligned to 8."""

    head: bytes
    tail: bytes


def _pad(out: bytearray, alignment: int) -> None:
    out += b'\0' * (-len(out) % alignment)


def _string(out: bytearray, text: str) -> None:
    data = text.encode()
    _pad(out, 4)
    out += _U32.pack(len(data) + 1)
    out += data
    out += b'\0'


def _time(out: bytearray, seconds: float | None) -> None:
    _pad(out, 4)
    out += _TIME.pack(*stamp_parts(seconds))


def encode_event(event: str, now: float, fields: Mapping[str, Any], reason: str) -> EncodedEvent:
    """A TaskEvent of `event` at `now` (wall-clock seconds) with the task's state (`fields`:
    task_messages.task_state_fields) and `reason`."""
    head = bytearray()
    _string(head, event)
    _time(head, now)
    for name in _HEAD_STRINGS:
        _string(head, fields[name])
    for name in _STAMPS:
        _time(head, fields[name])
    _string(head, fields['feedback'])
    _string(head, fields['task_result'])
    tail = bytearray(_SEQUENCE_AND_PAUSED.pack(fields['sequence'], fields['paused_sec']))
    _string(tail, fields['pauses'])
    _pad(tail, 4)
    tail += _POSITION_PRIORITY_ATTEMPT.pack(
        fields['queue_position'], fields['priority'], fields['attempt']
    )
    _string(tail, fields['decisions'])
    _string(tail, reason)
    return EncodedEvent(bytes(head), bytes(tail))


class EventBatchEncoding:
    """The array of encoded events (use `event_batch_encoding()`)."""

    def __init__(self, header: bytes) -> None:
        self._header = header

    def array(self, events: Sequence[EncodedEvent]) -> bytes:
        """The serialized TaskEventArray of these events, in this order."""
        data = bytearray(_U32.pack(len(events)))  # offsets count from here
        for head, tail in events:
            _pad(data, 4)
            data += head
            _pad(data, 8)
            data += tail
        return self._header + bytes(data)


def event_message(event: str, now: float, fields: Mapping[str, Any], reason: str) -> TaskEvent:
    """The same event as a message (for /task_manager/task_events, and for the check)."""
    return TaskEvent(
        event=event, stamp=stamp(now), task=task_state_of_fields(dict(fields)), reason=reason
    )


def _sample_fields(index: int) -> dict[str, Any]:
    """A task's fields whose strings' lengths put each event's 8-byte numbers at both
    alignments."""
    text = 'x' * index
    return {
        'task_id': f'id{text}',
        'task_name': 'navigation/go',
        'source': 'é' * index,  # UTF-8's bytes, not characters, count
        'task_status': 'IN_PROGRESS',
        'error_code': '',
        'mission_id': text,
        'received': 1_700_000_000.25 + index,
        'started': None if index % 2 else 1_700_000_001.5,
        'ended': None,
        'feedback': f'{{"left":{index}}}',
        'task_result': text * 3,
        'sequence': 2**40 + index,
        'paused_sec': 0.125 * index,
        'pauses': '[]',
        'queue_position': index,
        'priority': -index,
        'attempt': index + 1,
        'decisions': '[]' if index % 2 else '',
    }


@functools.cache
def event_batch_encoding() -> EventBatchEncoding | None:
    """The encoding, if what it writes for sample arrays is as long as what rclpy's serializer
    writes and rclpy reads it back as the same message (the padding bytes may differ); None
    otherwise."""
    samples = [
        ('STARTED', 1_700_000_002.0 + index, _sample_fields(index), 'r' * index)
        for index in range(5)
    ]
    encoding = EventBatchEncoding(serialize_message(TaskEventArray())[:4])
    for count in (len(samples), 0):
        message = TaskEventArray(events=[event_message(*s) for s in samples[:count]])
        written = encoding.array([encode_event(*s) for s in samples[:count]])
        if not written_as_serialized(written, message):
            return None
    return encoding
