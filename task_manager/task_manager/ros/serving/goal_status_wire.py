"""An action's status array (action_msgs/GoalStatusArray) as the bytes the middleware sends,
joined from each goal's part, encoded once per change of its status.

rclpy converts a message to C field by field in Python: an array of 1,000 goals took 3.5 ms
to publish here, and an action server lists every goal it keeps (an ended one for 10 s), each
time a status changes. A goal's part changes only with its status, so the array is a join of
parts made beforehand (publishing 1,000 then took 6 us). The layout is CDR's, as the
middleware's serializer writes it: the encapsulation header, the sequence's length, then per
goal its id's 16 bytes, the alignment to 4 (3 bytes, in every part but the first, which
starts aligned), the stamp's sec and nanosec, the status. `status_array_encoding()` checks
it once against rclpy's serializer; a middleware that writes other bytes gets None, and its
server publishes messages as before.
"""

import functools
import struct
from collections.abc import Sequence

from action_msgs.msg import GoalInfo, GoalStatus, GoalStatusArray
from builtin_interfaces.msg import Time
from rclpy.serialization import serialize_message
from unique_identifier_msgs.msg import UUID

from task_manager.rclpy_tools.wire import written_as_serialized

_LENGTH = struct.Struct('<I')
_STAMP_AND_STATUS = struct.Struct('<iIb')
_STATUS = struct.Struct('<b')
_ID_BYTES = 16
_ALIGNMENT = b'\0\0\0'
"""Between a goal's id and its stamp, in every part: the first part's is taken out of the
array (it starts 4-aligned, right after the length)."""
_ID_AND_ALIGNMENT = _ID_BYTES + len(_ALIGNMENT)


class StatusArrayEncoding:
    """Each goal's part, and the array joined from them (use `status_array_encoding()`)."""

    def __init__(self, header: bytes) -> None:
        self._header = header

    @staticmethod
    def part(goal_id: bytes, sec: int, nanosec: int, status: int) -> bytes:
        """One goal's part: its id (16 bytes), its stamp and its status."""
        return goal_id + _ALIGNMENT + _STAMP_AND_STATUS.pack(sec, nanosec, status)

    @staticmethod
    def with_status(part: bytes, status: int) -> bytes:
        """The same goal's part with another status (its last byte)."""
        return part[: -_STATUS.size] + _STATUS.pack(status)

    def array(self, parts: Sequence[bytes]) -> bytes:
        """The serialized GoalStatusArray listing these parts' goals, in this order."""
        body = b''.join(parts)
        return self._header + _LENGTH.pack(len(parts)) + body[:_ID_BYTES] + body[_ID_AND_ALIGNMENT:]


def part_of(status: GoalStatus) -> bytes:
    """The part of a GoalStatus message."""
    info = status.goal_info
    return StatusArrayEncoding.part(
        bytes(info.goal_id.uuid), info.stamp.sec, info.stamp.nanosec, status.status
    )


@functools.cache
def status_array_encoding() -> StatusArrayEncoding | None:
    """The encoding, if what it writes for a sample array is as long as what rclpy's
    serializer writes and rclpy reads it back as the same message (the alignment bytes may
    differ: the serializer leaves them unset); None otherwise."""
    sample = GoalStatusArray(
        status_list=[
            GoalStatus(
                goal_info=GoalInfo(
                    goal_id=UUID(uuid=list(range(16 * index + 1, 16 * index + 17))),
                    stamp=Time(sec=-2_000_000_000 + index, nanosec=4_000_000_000 + index),
                ),
                status=index,
            )
            for index in range(3)
        ]
    )
    encoding = StatusArrayEncoding(serialize_message(sample)[:4])
    written = encoding.array([part_of(status) for status in sample.status_list])
    return encoding if written_as_serialized(written, sample) else None
