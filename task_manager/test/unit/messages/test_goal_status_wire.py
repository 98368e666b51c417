"""The status array joined from each goal's part is what rclpy's serializer writes, and reads
back as the same message."""

from action_msgs.msg import GoalInfo, GoalStatus, GoalStatusArray
from builtin_interfaces.msg import Time
from hypothesis import given
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message, serialize_message
from unique_identifier_msgs.msg import UUID

from task_manager.ros.serving.goal_status_wire import (
    StatusArrayEncoding,
    part_of,
    status_array_encoding,
)

goal_statuses = st.builds(
    lambda goal_id, sec, nanosec, status: GoalStatus(
        goal_info=GoalInfo(goal_id=UUID(uuid=list(goal_id)), stamp=Time(sec=sec, nanosec=nanosec)),
        status=status,
    ),
    st.binary(min_size=16, max_size=16),
    st.integers(-(2**31), 2**31 - 1),
    st.integers(0, 2**32 - 1),
    st.integers(GoalStatus.STATUS_UNKNOWN, GoalStatus.STATUS_ABORTED),
)


def encoding() -> StatusArrayEncoding:
    found = status_array_encoding()
    assert found is not None, "the encoding does not write what this middleware's serializer does"
    return found


@given(st.lists(goal_statuses, max_size=8))
def test_the_joined_array_reads_back_as_the_message_and_is_as_long_as_rclpys(
    statuses: list[GoalStatus],
) -> None:
    message = GoalStatusArray(status_list=statuses)

    joined = encoding().array([part_of(status) for status in statuses])

    assert deserialize_message(joined, GoalStatusArray) == message
    assert len(joined) == len(serialize_message(message))


@given(goal_statuses, st.integers(GoalStatus.STATUS_UNKNOWN, GoalStatus.STATUS_ABORTED))
def test_a_part_with_another_status_is_the_part_of_the_goal_with_that_status(
    status: GoalStatus, new_status: int
) -> None:
    changed = StatusArrayEncoding.with_status(part_of(status), new_status)

    status.status = new_status
    assert changed == part_of(status)
