"""taskctl confirm and taskctl active with a waiting system/confirm, as a user runs them,
against a real node over DDS (the node's own semantics are in test_confirm.py)."""

import json
from collections.abc import Iterator

import pytest
from test_msgs.action import Fibonacci

from task_manager.client import TaskHandle, TaskManagerClient
from task_manager.core.names import CONFIRM
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.testing.harness import RosHarness
from task_manager.testing.process import LaunchTaskManager, action_task, taskctl
from task_manager.testing.servers import ScriptedActionServer

TIMEOUT_SEC = 15.0


@pytest.fixture
def client(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> Iterator[TaskManagerClient]:
    """A client of a node with one task, `photo`."""
    ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/photo')
    launch_task_manager({'photo': action_task('photo', f'{topic_prefix}/photo')})
    with TaskManagerClient('test_taskctl_confirm', timeout_sec=TIMEOUT_SEC) as client:
        yield client


def start_waiting(client: TaskManagerClient, task_id: str, prompt: str) -> TaskHandle:
    handle = client.start_task(CONFIRM, {'prompt': prompt}, task_id=task_id)
    next(handle.feedback(TIMEOUT_SEC))
    return handle


def test_taskctl_active_shows_the_prompt_and_taskctl_confirm_answers_it(
    client: TaskManagerClient,
) -> None:
    handle = start_waiting(client, 'tray', 'Load the tray, then confirm')

    table = taskctl('active')
    as_json = taskctl('active', '--json')
    confirmed = taskctl('confirm', 'tray', '--comment', 'tray loaded')
    result = handle.result(TIMEOUT_SEC)
    again = taskctl('confirm', 'tray')

    assert table.returncode == 0, table.stderr
    assert as_json.returncode == 0, as_json.stderr
    assert 'waiting for an answer' in table.stdout
    assert 'Load the tray, then confirm' in table.stdout
    assert [json.loads(line)['prompt'] for line in as_json.stdout.splitlines()] == [
        'Load the tray, then confirm'
    ]
    assert (confirmed.returncode, confirmed.stdout) == (0, 'tray  confirmed\n'), confirmed.stderr
    assert (result.status, result.result) == (
        TaskStatus.DONE,
        {'confirmed': True, 'by': 'CLI', 'comment': 'tray loaded', 'outcome': 'confirmed'},
    )
    assert again.returncode == 1
    assert again.stderr.strip() == (
        "not_waiting: task 'tray' (system/confirm) has ended DONE; it takes no more answers"
    )


def test_taskctl_confirm_rejects_as_its_source_and_says_why_an_id_takes_no_answer(
    client: TaskManagerClient,
) -> None:
    handle = start_waiting(client, 'gate', 'Is the gate open?')

    rejected = taskctl('confirm', 'gate', '--reject', '--source', 'ops')
    result = handle.result(TIMEOUT_SEC)
    unknown = taskctl('confirm', 'ghost')

    assert (rejected.returncode, rejected.stdout) == (0, 'gate  rejected\n'), rejected.stderr
    assert (result.status, result.error_code) == (TaskStatus.ERROR, ErrorCode.REJECTED)
    assert (result.result['by'], result.result['outcome']) == ('ops', 'rejected')
    assert (unknown.returncode, unknown.stdout) == (1, '')
    assert unknown.stderr.strip() == (
        "not_found: no task 'ghost': none is active, and none is in the history"
    )
