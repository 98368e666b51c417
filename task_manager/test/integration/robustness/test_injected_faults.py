"""A failure of ours at any step after a goal was sent neither frees the goal from tracking nor
stops the node: the goal is cancelled, the task ends once its server says so, and the node
goes on serving (the node runs with one fault injected, see testing/faulty_node.py)."""

import json
import sys

import pytest
from test_msgs.action import Fibonacci

from task_manager.testing import faulty_node
from task_manager.testing.harness import RosHarness
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer

pytestmark = pytest.mark.ros
TIMEOUT_SEC = 15.0
AFTER_THE_SEND = [step for step in faulty_node.STEPS if step != 'deadline_timer']
WATCH = {'server_check_period': 0.2}


@pytest.fixture
def node_wrapper(step: str) -> list[str]:
    """The node runs with a fault injected at `step` (the test's parameter)."""
    return [sys.executable, '-m', 'task_manager.testing.faulty_node', step]


@pytest.mark.parametrize('step', AFTER_THE_SEND)
def test_a_failure_after_the_send_cancels_the_goal_and_the_node_serves_on(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, step: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/drive')
    tm = launch_task_manager({'drive': action_task('drive', f'{topic_prefix}/drive')}, **WATCH)

    first = tm.result_of(tm.send('drive', {'order': 1}, task_id='faulted')).result

    goal = server.wait_for_goals(1, TIMEOUT_SEC)[0]
    assert goal.cancel_requested.is_set()  # not left running untracked
    assert goal.ended.is_set()  # the task ended once its server said so
    assert (first.task_status, first.error_code) == ('ERROR', 'task_start_failed')
    error = json.loads(first.task_result)['error']
    assert f'injected at {step}' in error and 'cancelled on its server' in error
    tm.wait_active(lambda tasks: tasks == [], 'no active task left')
    assert [m.task_status for m in tm.results_for('faulted')] == ['ERROR']
    # the fault was one call: the node goes on serving
    second = tm.send('drive', {'order': 1}, task_id='after')
    server.wait_for_goals(2, TIMEOUT_SEC)[1].succeed()
    assert tm.result_of(second).result.task_status == 'DONE'


@pytest.mark.parametrize('step', ['deadline_timer'])
def test_a_failure_in_the_deadline_timer_does_not_stop_the_node(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, step: str
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/drive')
    tm = launch_task_manager(
        {'drive': action_task('drive', f'{topic_prefix}/drive', timeout_sec=0.5)}, **WATCH
    )

    ended = tm.result_of(tm.send('drive', {'order': 1}, task_id='timed')).result

    # the timer's next call found the deadline: the timeout still ends the task
    assert (ended.task_status, ended.error_code) == ('ERROR', 'timeout')
    assert server.wait_for_goals(1, TIMEOUT_SEC)[0].cancel_requested.is_set()
    log = tm.process.wait_for_log(r'a callback failed and was dropped.*', TIMEOUT_SEC)
    assert 'injected at deadline_timer' in log
