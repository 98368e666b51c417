"""What a task keeps of its decisions is bounded, against a real node: a task reprioritized
again and again keeps its first and its newest decisions and counts those left out, in `why`,
its state and the history."""

from collections.abc import Iterator

import pytest
from test_msgs.action import Fibonacci

from task_manager.client import TaskManagerClient
from task_manager.core.admission.decisions import KEPT_FIRST
from task_manager.core.bounds import DECISIONS_PER_TASK_MAX
from task_manager.core.status import TaskStatus
from task_manager.testing.harness import RosHarness
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer

TIMEOUT_SEC = 15.0
REPRIORITIZED = 150


@pytest.fixture
def client() -> Iterator[TaskManagerClient]:
    with TaskManagerClient('test_decisions_bound', timeout_sec=TIMEOUT_SEC) as client:
        yield client


def test_a_task_reprioritized_150_times_keeps_100_decisions_and_counts_the_rest(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/drive')
    launch_task_manager({'drive': action_task('drive', f'{topic_prefix}/drive')})
    client.wait_until_available()
    handle = client.start_task('drive', {'order': 1}, task_id='drive-1')
    goal = server.wait_for_goals(1, TIMEOUT_SEC)[0]

    for priority in range(1, REPRIORITIZED + 1):
        assert client.reprioritize(['drive-1'], priority).ok
    why = client.why('drive-1')
    (state,) = client.task_states(['drive-1'])
    goal.succeed()
    assert handle.result(TIMEOUT_SEC).status is TaskStatus.DONE
    (ended,) = client.history(task_name='drive', limit=1)

    left_out = REPRIORITIZED - (DECISIONS_PER_TASK_MAX - 1)
    assert len(why) == DECISIONS_PER_TASK_MAX
    assert [d.reason for d in why[:2]] == [
        'priority 0 -> 1, by python',
        'priority 1 -> 2, by python',
    ]
    assert (why[KEPT_FIRST].decision, why[KEPT_FIRST].omitted) == ('omitted', left_out)
    assert why[-1].reason == f'priority {REPRIORITIZED - 1} -> {REPRIORITIZED}, by python'
    assert state.decisions == why
    assert ended.decisions == why
