"""The demo's retried task: `cloud/upload_photos`, declared with three attempts in
demo_tasks.yaml, against the simulated robot's uplink, which drops as many uploads in a row as
a request says."""

from collections.abc import Iterator

import pytest

from task_manager.client import TaskManagerClient
from task_manager.core.status import TaskStatus
from task_manager_demo.testing import demo_robot

TIMEOUT_SEC = 15.0
UPLOAD = 'cloud/upload_photos'

pytestmark = pytest.mark.ros


@pytest.fixture(scope='module')
def client(ros_context: None) -> Iterator[TaskManagerClient]:
    """The simulated robot, the Task Manager with the demo's tasks, and a client of it."""
    with demo_robot('demo_retry_test', client_timeout_sec=TIMEOUT_SEC) as client:
        yield client


def test_an_upload_the_link_drops_twice_ends_done_on_its_third_attempt(
    client: TaskManagerClient,
) -> None:
    result = client.run_task(UPLOAD, {'drops': 2}, task_id='upload-1', timeout_sec=TIMEOUT_SEC)

    assert (result.status, result.result['success']) == (TaskStatus.DONE, True), result
    (state,) = client.task_states(['upload-1'])
    assert state.attempt == 3
    retries = [d.reason for d in state.decisions if d.decision == 'retry']
    assert retries == [
        'retry: attempt 1 of 3 ended ERROR (its server failed it); attempt 2 in 0.5 s',
        'retry: attempt 2 of 3 ended ERROR (its server failed it); attempt 3 in 1 s',
    ]


def test_an_upload_the_link_drops_three_times_ends_error_after_three_attempts(
    client: TaskManagerClient,
) -> None:
    result = client.run_task(UPLOAD, {'drops': 3}, task_id='upload-2', timeout_sec=TIMEOUT_SEC)

    assert result.status is TaskStatus.ERROR, result
    assert result.result['message'] == 'the link dropped the upload (3 of 3 in a row)'
    (state,) = client.task_states(['upload-2'])
    assert state.attempt == 3
    assert state.decisions[-1].reason == (
        'gave up: attempt 3 of 3 ended ERROR (its server failed it); no attempt left'
    )
