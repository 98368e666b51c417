"""Messages written as the middleware's bytes by hand (the node's status arrays and event
batches), checked against rclpy's serializer before they are used."""

from typing import Any

from rclpy.serialization import deserialize_message, serialize_message


def written_as_serialized(written: bytes, message: Any) -> bool:
    """Whether `written` is what rclpy's serializer writes for `message`: as long, and read
    back as the same message (the padding bytes may differ: the serializer leaves them unset)."""
    if len(written) != len(serialize_message(message)):
        return False
    try:
        read_back = deserialize_message(written, type(message))
    except RuntimeError:  # rclpy's RMWError: bytes its middleware cannot read
        return False
    return bool(read_back == message)
