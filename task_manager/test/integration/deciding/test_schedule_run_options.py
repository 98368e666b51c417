"""A schedule's run options (issue 29) against a real node: schedules made by taskctl and by
the Python client with on_conflict queue and a priority queue their runs behind a task that
holds the resource, by priority, and the listings show the options."""

import json
from collections.abc import Iterator

import pytest
from test_msgs.action import Fibonacci

from task_manager.client import TaskManagerClient
from task_manager.core.status import TaskStatus
from task_manager.testing.harness import RosHarness
from task_manager.testing.process import LaunchTaskManager, action_task, taskctl
from task_manager.testing.servers import ScriptedActionServer

TIMEOUT_SEC = 15.0


@pytest.fixture
def client() -> Iterator[TaskManagerClient]:
    with TaskManagerClient('test_schedule_options', timeout_sec=TIMEOUT_SEC) as client:
        yield client


def test_scheduled_runs_queue_with_their_priority_and_the_listing_shows_the_options(
    ros: RosHarness,
    launch_task_manager: LaunchTaskManager,
    topic_prefix: str,
    client: TaskManagerClient,
) -> None:
    tasks = {
        name: action_task(name, f'{topic_prefix}/{name}', resources=['base'], reentrant=True)
        for name in ('drive', 'dock')
    }
    drive, dock = (
        ScriptedActionServer(ros.node, Fibonacci, tasks[name]['topic']) for name in tasks
    )
    tm = launch_task_manager(tasks)
    client.wait_until_available()
    holder = client.start_task('drive', {'order': 1}, task_id='drive-1', priority=5)
    tm.wait_in_progress('drive-1')

    added = taskctl(
        'schedule', 'add', 'dock', '{"order": 2}', '--id', 'by-cli', '--in', '0.1s',
        '--priority', '2', '--on-conflict', 'queue', '--queue-timeout', '30',
    )  # fmt: skip
    assert added.returncode == 0, added.stderr
    tm.wait_active(lambda active: ('by-cli-run-1', 'QUEUED') in active, 'by-cli-run-1 queued')
    by_client = client.schedule_task(
        'dock', {'order': 3}, schedule_id='by-client', delay=0.1, priority=3, on_conflict='queue'
    )
    assert by_client.ok, by_client.result
    tm.wait_active(lambda active: ('by-client-run-1', 'QUEUED') in active, 'by-client-run-1 queued')

    states = {s.task_id: s for s in client.task_states(['by-cli-run-1', 'by-client-run-1'])}
    assert [
        (states[i].status, states[i].priority, states[i].queue_position)
        for i in ('by-client-run-1', 'by-cli-run-1')
    ] == [(TaskStatus.QUEUED, 3, 1), (TaskStatus.QUEUED, 2, 2)]
    options = {info.schedule_id: info.options for info in client.schedules()}
    assert options == {
        'by-cli': {'priority': 2, 'on_conflict': 'queue', 'queue_timeout_sec': 30.0},
        'by-client': {'priority': 3, 'on_conflict': 'queue'},
    }
    listed = taskctl('schedule', 'list', '--json')
    table = taskctl('schedule', 'list')
    assert listed.returncode == table.returncode == 0, listed.stderr + table.stderr
    rows = {
        row['schedule_id']: row['options'] for row in map(json.loads, listed.stdout.splitlines())
    }
    assert rows == options
    assert 'priority=2 on_conflict=queue queue_timeout_sec=30' in table.stdout

    # the holder ends: the run of higher priority starts first, then the other
    drive.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    assert holder.result(TIMEOUT_SEC).status is TaskStatus.DONE
    first = dock.wait_for_goals(1, TIMEOUT_SEC)[0]
    assert first.request.order == 3
    first.succeed()
    second = dock.wait_for_goals(2, TIMEOUT_SEC)[1]
    assert second.request.order == 2
    second.succeed()
    assert tm.wait_result_message('by-cli-run-1').task_status == 'DONE'
