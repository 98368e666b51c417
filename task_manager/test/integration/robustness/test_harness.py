"""The tests' RosHarness: a callback that raises is reported where it happened, at close, and
the node goes on serving the test meanwhile."""

import pytest

from task_manager.testing.harness import CallbackError, RosHarness

pytestmark = pytest.mark.ros


def test_a_raising_callback_is_raised_at_close_and_the_executor_goes_on_meanwhile(
    ros_context: None,
) -> None:
    harness = RosHarness('harness_raising_callback')

    def broken_double() -> None:
        raise ValueError('the test double broke')

    harness.node.create_guard_condition(broken_double).trigger()

    assert harness.on_executor(lambda: 'still spinning') == 'still spinning'
    with pytest.raises(CallbackError, match='the test double broke') as raised:
        harness.close()
    assert isinstance(raised.value.__cause__, ValueError)


def test_a_harness_whose_callbacks_all_returned_closes_quietly(ros_context: None) -> None:
    harness = RosHarness('harness_quiet')

    assert harness.on_executor(lambda: 1) == 1
    harness.close()
    assert harness.callback_errors == []
