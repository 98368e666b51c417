"""The dashboard in a real headless Chromium (Debian's), against a real gateway and node.

Playwright drives the browser at /usr/bin/chromium; it never downloads one. The node serves
the gateways' tests' robot (`fib`, `instant`) and `drive`, a task on resource `base` that
queues (on_conflict: queue) behind a drive running.
"""

from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import pytest
import yaml
from playwright.sync_api import APIResponse, Page, expect
from test_msgs.action import Fibonacci

from task_manager.testing.gateway import TIMEOUT_SEC, Robot, ScriptedRobot
from task_manager.testing.harness import RosHarness
from task_manager.testing.process import action_task, write_params_file
from task_manager.testing.servers import ScriptedActionServer
from task_manager_web.testing import GatewayProcess, HeldRead

pytestmark = pytest.mark.ros


def drive_topic(tmp_path: Path) -> str:
    return f'/d{abs(hash(tmp_path)) % 10**8}/drive'


@pytest.fixture
def drive(ros: RosHarness, tmp_path: Path) -> Iterator[ScriptedActionServer]:
    """The server of the task `drive`."""
    server = ScriptedActionServer(ros.node, Fibonacci, drive_topic(tmp_path))
    yield server
    server.destroy()


@pytest.fixture
def start_robot(
    ros: RosHarness, tmp_path: Path, drive: ScriptedActionServer
) -> Iterator[Callable[[], Robot]]:
    """The gateways' robot (see ScriptedRobot), with `drive` declared too."""
    robot = ScriptedRobot(ros, tmp_path)
    parameters = yaml.safe_load(robot.params.read_text())['task_manager']['ros__parameters']
    parameters['tasks'].append('drive')
    parameters['drive'] = action_task(
        'drive', drive_topic(tmp_path), resources=['base'], on_conflict='queue'
    )
    write_params_file(robot.params, parameters)
    yield robot.start
    robot.close()


def test_start_a_task_from_its_generated_form_and_see_it_run_and_end(
    page: Page, robot: Robot
) -> None:
    assert 'token' not in page.url  # taken out of the address bar once read
    page.select_option('#task-select', 'fib')
    page.fill('[data-field="order"]', '6')
    page.click('#start-button')

    (goal,) = robot.fib.wait_for_goals(1, TIMEOUT_SEC)
    assert goal.request.order == 6
    expect(page.locator('#message')).to_contain_text('Started fib: ')
    task_id = page.locator('#message').inner_text().rsplit(' ', 1)[-1]
    row = page.locator(f'#active tbody tr[data-task-id="{task_id}"]')
    expect(row).to_contain_text('IN_PROGRESS')
    expect(row).to_contain_text('WEB')

    goal.succeed()

    history_row = page.locator(f'#history tbody tr[data-task-id="{task_id}"]')
    expect(history_row).to_contain_text('DONE')
    expect(row).to_have_count(0)  # gone from the active tasks a moment after its end


def test_a_mission_shows_as_a_row_of_steps_that_advance(
    page: Page, robot: Robot, api: httpx.Client
) -> None:
    subtasks = [{'task_name': 'fib', 'task_data': {'order': n}} for n in (1, 2)]
    api.post('/api/missions', json={'subtasks': subtasks, 'task_id': 'shown-mission'})
    mission = page.locator('.mission[data-mission-id="shown-mission"]')
    steps = mission.locator('.step')

    expect(steps.nth(0)).to_have_attribute('data-state', 'running')
    expect(steps.nth(1)).to_have_attribute('data-state', 'pending')
    robot.fib.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    expect(steps.nth(0)).to_have_attribute('data-state', 'done')
    expect(steps.nth(1)).to_have_attribute('data-state', 'running')
    robot.fib.wait_for_goals(2, TIMEOUT_SEC)[1].succeed()
    expect(steps.nth(1)).to_have_attribute('data-state', 'done')
    expect(mission.locator('.mission-title')).to_contain_text('DONE')


@pytest.fixture
def held_read(open_holding_first_read: Callable[[str], HeldRead]) -> HeldRead:
    """The dashboard opened, its first read of the active tasks (made at the connection)
    held unanswered."""
    return open_holding_first_read('**/api/active')


def answer_read(read: HeldRead, answer: APIResponse) -> None:
    """Answers the held read of the active tasks; returns once the page has taken the answer
    (it reads the history next)."""
    with read.page.expect_request('**/api/history*'):
        read.route.fulfill(response=answer)


def test_a_task_started_while_the_active_list_is_read_stays_shown_after_the_older_answer(
    blank_page: Page, held_read: HeldRead, api: httpx.Client, robot: Robot
) -> None:
    page = blank_page
    older = held_read.fetch()  # no task yet
    api.post(
        '/api/tasks/start', json={'task_name': 'fib', 'task_data': {'order': 1}, 'task_id': 'new'}
    )
    row = page.locator('#active tbody tr[data-task-id="new"]')
    expect(row).to_contain_text('IN_PROGRESS')

    answer_read(held_read, older)

    expect(row).to_contain_text('IN_PROGRESS')
    robot.fib.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    expect(page.locator('#history tbody tr[data-task-id="new"]')).to_contain_text('DONE')


def test_a_mission_step_that_started_while_the_active_list_is_read_stays_running(
    blank_page: Page, held_read: HeldRead, api: httpx.Client, robot: Robot
) -> None:
    page = blank_page
    subtasks = [{'task_name': 'fib', 'task_data': {'order': n}} for n in (1, 2)]
    api.post('/api/missions', json={'subtasks': subtasks, 'task_id': 'read-mission'})
    steps = page.locator('.mission[data-mission-id="read-mission"] .step')
    expect(steps.nth(0)).to_have_attribute('data-state', 'running')
    older = held_read.fetch()  # step 1 running, step 2 pending
    robot.fib.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    expect(steps.nth(1)).to_have_attribute('data-state', 'running')

    answer_read(held_read, older)

    expect(steps.nth(0)).to_have_attribute('data-state', 'done')
    expect(steps.nth(1)).to_have_attribute('data-state', 'running')
    robot.fib.wait_for_goals(2, TIMEOUT_SEC)[1].succeed()
    expect(steps.nth(1)).to_have_attribute('data-state', 'done')


def test_stop_cancels_the_running_tasks(page: Page, robot: Robot, api: httpx.Client) -> None:
    api.post(
        '/api/tasks/start',
        json={'task_name': 'fib', 'task_data': {'order': 1}, 'task_id': 'to-stop'},
    )
    (goal,) = robot.fib.wait_for_goals(1, TIMEOUT_SEC)
    expect(page.locator('#active tbody tr[data-task-id="to-stop"]')).to_contain_text('IN_PROGRESS')

    page.click('#stop')

    assert goal.cancel_requested.wait(TIMEOUT_SEC)
    expect(page.locator('#message')).to_contain_text('STOP: DONE')
    expect(page.locator('#history tbody tr[data-task-id="to-stop"]')).to_contain_text('CANCELED')


def test_the_dashboard_says_when_the_node_is_gone_and_recovers_by_itself(
    page: Page, robot: Robot, start_robot: Callable[[], Robot]
) -> None:
    robot.process.stop()

    expect(page.locator('#connection')).to_have_text('Task Manager not reachable')
    expect(page.locator('#banner')).to_contain_text('stale, not running')
    expect(page.locator('body')).to_have_class('stale')
    start_robot()
    expect(page.locator('#connection')).to_have_text('connected')
    expect(page.locator('#banner')).to_be_hidden()
    expect(page.locator('body')).not_to_have_class('stale')


def test_the_api_docs_render_under_the_content_security_policy(
    blank_page: Page, gateway: GatewayProcess
) -> None:
    page = blank_page

    page.goto(f'{gateway.url}/docs')

    expect(page.locator('#swagger-ui')).to_contain_text('/api/tasks/start')
    page.locator('.opblock-summary', has_text='/api/tasks/start').click()  # its body's schema
    expect(page.locator('.opblock-body').first).to_contain_text('task_name')
    expect(page.locator('.models')).to_contain_text('StartTask')


def test_queued_tasks_show_their_place_and_priority_which_the_operator_changes_or_cancels(
    page: Page, drive: ScriptedActionServer, api: httpx.Client
) -> None:
    for task_id in ('drive-1', 'drive-2', 'drive-3'):
        start = {'task_name': 'drive', 'task_data': {'order': 1}, 'task_id': task_id}
        assert api.post('/api/tasks/start', json=start).status_code == 202
    (running,) = drive.wait_for_goals(1, TIMEOUT_SEC)
    rows = page.locator('#active tbody tr')
    second, third = (rows.and_(page.locator(f'[data-task-id="drive-{n}"]')) for n in (2, 3))
    expect(second.locator('.badge')).to_have_text('QUEUED')
    expect(second.locator('.queue-position')).to_have_text('#1')
    expect(third.locator('.queue-position')).to_have_text('#2')
    expect(second.locator('.priority-value')).to_have_text('0')
    expect(second.locator('.reason')).to_contain_text('queued behind drive-1')

    third.locator('button.reprioritize').click()
    page.fill('#priority-input', '5')
    page.click('#priority-set')

    expect(page.locator('#message')).to_have_text('Priority of drive-3: 5')
    expect(third.locator('.priority-value')).to_have_text('5')
    expect(third.locator('.queue-position')).to_have_text('#1')
    expect(second.locator('.queue-position')).to_have_text('#2')
    expect(rows.nth(1)).to_have_attribute('data-task-id', 'drive-3')  # the queue in its order

    second.locator('button.cancel').click()

    history_row = page.locator('#history tbody tr[data-task-id="drive-2"]')
    expect(history_row).to_contain_text('CANCELED')
    expect(third.locator('.queue-position')).to_have_text('#1')
    assert not running.cancel_requested.is_set()  # the running drive goes on
    running.succeed()
    expect(third.locator('.badge')).to_have_text('IN_PROGRESS')
    drive.wait_for_goals(2, TIMEOUT_SEC)[1].succeed()
    expect(page.locator('#history tbody tr[data-task-id="drive-3"]')).to_contain_text('DONE')


def test_the_start_form_sends_a_priority_and_what_to_do_on_a_conflict(
    page: Page, drive: ScriptedActionServer, api: httpx.Client
) -> None:
    start = {'task_name': 'drive', 'task_data': {'order': 1}, 'task_id': 'drive-1'}
    assert api.post('/api/tasks/start', json=start).status_code == 202
    (running,) = drive.wait_for_goals(1, TIMEOUT_SEC)
    page.select_option('#task-select', 'drive')

    page.select_option('#start-on-conflict', 'reject')
    page.click('#start-button')

    expect(page.locator('#message')).to_contain_text('Started drive: ')
    refused_id = page.locator('#message').inner_text().rsplit(' ', 1)[-1]
    refused = page.locator(f'#history tbody tr[data-task-id="{refused_id}"]')
    expect(refused).to_contain_text('ERROR')
    expect(refused).to_contain_text('drive-1')  # the reason names the holder of base

    page.select_option('#start-on-conflict', '')
    page.fill('#start-priority', '7')
    page.click('#start-button')

    expect(page.locator('#message')).not_to_contain_text(refused_id)
    queued_id = page.locator('#message').inner_text().rsplit(' ', 1)[-1]
    queued = page.locator(f'#active tbody tr[data-task-id="{queued_id}"]')
    expect(queued.locator('.badge')).to_have_text('QUEUED')
    expect(queued.locator('.priority-value')).to_have_text('7')
    running.succeed()
    expect(queued.locator('.badge')).to_have_text('IN_PROGRESS')
    drive.wait_for_goals(2, TIMEOUT_SEC)[1].succeed()
