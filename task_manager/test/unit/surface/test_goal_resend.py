"""When the client sends a goal not answered again (goal_resend_offsets); the timeouts it
and taskctl take."""

import pytest
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

from task_manager.cli import main as cli_main
from task_manager.client.connection import GOAL_RESEND_WITHIN_SEC, SERVICE_RETRY_SEC
from task_manager.client.tasks import goal_resend_offsets


def test_a_goal_is_sent_again_after_half_a_second_then_twice_as_long_each_time() -> None:
    assert goal_resend_offsets(60.0) == [0.5, 1.5, 3.5, 7.5]
    assert goal_resend_offsets(2.0) == [0.5, 1.5]


@given(st.floats(min_value=0.0, max_value=3600.0))
def test_never_as_the_caller_gives_up_nor_once_the_node_may_have_forgotten_the_goal(
    timeout_sec: float,
) -> None:
    """A goal sent at or past the caller's timeout would start a task the caller was told did
    not start; one sent after the node forgot an ended goal would run it again."""
    offsets = goal_resend_offsets(timeout_sec)

    assert all(at < min(timeout_sec, GOAL_RESEND_WITHIN_SEC) for at in offsets)
    assert offsets == [SERVICE_RETRY_SEC * (2 ** (n + 1) - 1) for n in range(len(offsets))]


@pytest.mark.parametrize('timeout', ['inf', 'nan', '-1', '700000'])
def test_taskctl_refuses_a_timeout_its_client_cannot_wait(timeout: str) -> None:
    """A usage error (exit 2) before any ROS work, not a traceback from the client."""
    outcome = CliRunner().invoke(cli_main.app, ['--timeout', timeout, 'tasks'])

    assert outcome.exit_code == 2
    assert '--timeout must be' in outcome.output
