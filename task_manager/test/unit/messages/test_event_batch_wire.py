"""Event batches encoded from each event's fields are what rclpy's serializer writes for the
same messages, and read back as them, at every alignment the strings' lengths give."""

from typing import Any

from hypothesis import given
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message, serialize_message
from task_manager_msgs.msg import TaskEventArray

from task_manager.rclpy_tools.wire import written_as_serialized
from task_manager.ros.recording.event_batch_wire import (
    EventBatchEncoding,
    _sample_fields,
    encode_event,
    event_batch_encoding,
    event_message,
)

# what a ROS string carries: no NUL (the node's texts are JSON, or ids with no control character)
texts = st.text(st.characters(codec='utf-8', exclude_characters='\0'), max_size=12)
seconds = st.one_of(st.none(), st.floats(0, 2**31 - 2, allow_nan=False))
TEXT_FIELDS = (
    'task_id', 'task_name', 'source', 'task_status', 'error_code', 'mission_id', 'feedback',
    'task_result', 'pauses', 'decisions',
)  # fmt: skip
fields = st.fixed_dictionaries(
    {
        **dict.fromkeys(TEXT_FIELDS, texts),
        'received': seconds,
        'started': seconds,
        'ended': seconds,
        'sequence': st.integers(0, 2**64 - 1),
        'paused_sec': st.floats(allow_nan=False),
        'queue_position': st.integers(0, 2**32 - 1),
        'priority': st.integers(-(2**31), 2**31 - 1),
        'attempt': st.integers(0, 2**32 - 1),
    }
)
events = st.tuples(texts, st.floats(0, 2**31 - 2, allow_nan=False), fields, texts)


def encoding() -> EventBatchEncoding:
    found = event_batch_encoding()
    assert found is not None, "the encoding does not write what this middleware's serializer does"
    return found


@given(st.lists(events, max_size=6))
def test_an_encoded_batch_reads_back_as_its_messages_and_is_as_long_as_rclpys(
    batch: list[tuple[str, float, dict[str, Any], str]],
) -> None:
    message = TaskEventArray(events=[event_message(*event) for event in batch])

    encoded = encoding().array([encode_event(*event) for event in batch])

    assert deserialize_message(encoded, TaskEventArray) == message
    assert len(encoded) == len(serialize_message(message))


def test_bytes_the_serializer_would_not_write_are_told_apart() -> None:
    """The check made once at start: bytes shorter, or that read back as another message, are
    not taken for the message's."""
    message = TaskEventArray(events=[event_message('ENDED', 1.5, _sample_fields(3), 'why')])
    serialized = serialize_message(message)
    other_text = serialized.replace(b'why', b'who')

    assert written_as_serialized(serialized, message)
    assert not written_as_serialized(serialized[:-4], message)
    assert not written_as_serialized(other_text, message)
