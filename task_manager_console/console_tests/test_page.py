"""The console's page (issue 38, item 4) in a real headless Chromium (Debian's, driven by
Playwright, which never downloads one), against `task-manager-console` as users run it on a real
mosquitto: simulated robots for what the page shows, the demo's real robots (Task Manager and
bridge, each in a ROS domain of its own) for what it does: STOP ALL reaching every robot, a start
on "any robot" landing on the free one, a confirmation answered from the banner."""

import os
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, cast

from playwright.sync_api import Page, expect
from task_manager_web.doors_testing import OPERATOR, TOKENS, VIEWER
from task_manager_web.doors_testing import blank_page as blank_page
from task_manager_web.doors_testing import browser as browser

from task_manager_console.doors_testing import ConsoleProcess, wait_for
from task_manager_console.simulation.robot import SimulatedRobot

SCREENSHOT = Path(__file__).parents[2] / 'docs' / 'images' / 'console.png'
SCREENSHOT_ASKED = 'TASK_MANAGER_SCREENSHOTS'
"""Set (to 1) to write the docs' screenshot again (else the test leaves the work tree alone)."""
NAVIGATE = 'navigation/navigate_to_pose'
Document = dict[str, Any]


def open_page(page: Page, console: ConsoleProcess, role: str) -> Page:
    """The page, opened with the token of `role` in its address, once its stream is open."""
    page.goto(f'{console.url}/?token={TOKENS[role]}')
    expect(page.locator('#connection')).to_have_text('connected')
    return page


def card(page: Page, robot_id: str) -> Any:
    return page.locator(f'#robots article[data-robot-id="{robot_id}"]')


def task(
    task_id: str, task_name: str = 'fib', status: str = 'IN_PROGRESS', **fields: Any
) -> Document:
    """An active Task document, as a bridge sends it."""
    now = datetime.now(UTC).isoformat()
    return {
        'task_id': task_id, 'task_name': task_name, 'source': 'CLOUD', 'status': status,
        'received': now, 'started': now if status == 'IN_PROGRESS' else None, **fields,
    }  # fmt: skip


# ---- what the page shows (simulated robots) ------------------------------------------------


def test_a_card_per_robot_shows_its_state_active_task_queue_and_last_result_as_they_change(
    console: ConsoleProcess,
    blank_page: Page,
    start_robot_on: Callable[..., SimulatedRobot],
) -> None:
    busy = start_robot_on('robot1')
    away = start_robot_on('robot2')
    away.go_offline()
    broken = start_robot_on('robot3')
    broken.vanish()
    page = open_page(blank_page, console, VIEWER)
    assert 'token' not in page.url  # taken out of the address bar once read

    expect(card(page, 'robot2').locator('.connection-state')).to_have_text('OFFLINE')
    expect(card(page, 'robot3').locator('.connection-state')).to_have_text('CONNECTIONBROKEN')
    expect(card(page, 'robot1').locator('.connection-state')).to_have_text('ONLINE')
    expect(card(page, 'robot1').locator('.active-task')).to_have_text('idle')
    expect(page.locator('#fleet-count')).to_have_text('1 of 3 robots online')

    busy.set_active([
        task('long', feedback={'progress': 0.25}),
        task('next', status='QUEUED', queue_position=1),
        task('after', status='QUEUED', queue_position=2),
    ])  # fmt: skip
    robot1 = card(page, 'robot1')
    expect(robot1.locator('.active-task')).to_contain_text('fib')
    expect(robot1.locator('.active-task')).to_contain_text('IN_PROGRESS')
    expect(robot1.locator('.active-task')).to_have_attribute('data-task-id', 'long')
    expect(robot1.locator('progress')).to_have_attribute('value', '0.25')
    expect(robot1.locator('.queue-length')).to_have_text('2')

    [result] = busy.send_results(1, task_id='ended-one', status='ERROR')
    expect(robot1.locator('.last-result')).to_have_attribute('data-task-id', 'ended-one')
    expect(robot1.locator('.last-result')).to_contain_text('ERROR')
    row = page.locator('#history tbody tr[data-robot-id="robot1"][data-task-id="ended-one"]')
    expect(row).to_contain_text('ERROR')
    assert result['task_id'] == 'ended-one'

    # the viewer sees no control
    expect(page.locator('#stop-all')).to_be_hidden()
    expect(page.locator('#start-form')).to_be_hidden()


def test_the_history_filters_by_robot_and_a_confirmation_waiting_on_any_robot_is_in_the_banner(
    console: ConsoleProcess,
    blank_page: Page,
    start_robot_on: Callable[..., SimulatedRobot],
) -> None:
    first = start_robot_on('robot1')
    second = start_robot_on('robot2')
    first.send_results(2)
    second.send_results(1, task_id='of-robot2')
    page = open_page(blank_page, console, OPERATOR)
    rows = page.locator('#history tbody tr')
    expect(rows).to_have_count(3)

    page.fill('#history-filters [name="robot_id"]', 'robot2')
    page.click('#history-filters button[type="submit"]')
    expect(rows).to_have_count(1)
    expect(rows.first).to_have_attribute('data-task-id', 'of-robot2')
    first.send_results(1)  # streamed, but not robot2's: not shown
    second.send_results(1, task_id='of-robot2-again')
    expect(rows.first).to_have_attribute('data-task-id', 'of-robot2-again')
    expect(rows).to_have_count(2)

    waiting = task(
        'tray', 'system/confirm', feedback={'prompt': 'Load the tray', 'remaining_sec': 60}
    )
    second.set_active([waiting])
    item = page.locator('#confirmations .confirmation[data-robot-id="robot2"]')
    expect(item).to_have_attribute('data-task-id', 'tray')
    expect(item.locator('.confirm-prompt')).to_have_text('Load the tray')
    expect(item.locator('.countdown')).to_contain_text('left')
    assert page.title().startswith('(1) waiting for confirmation')
    second.set_active([])
    expect(page.locator('#confirmations')).to_be_hidden()


# ---- what the page does (real robots) ------------------------------------------------------


def stored(console: ConsoleProcess, task_id: str) -> Document:
    """Wait until the fleet history has the task's result; it."""
    with console.client(VIEWER) as http:
        found = wait_for(
            lambda: http.get('/api/history', params={'task_id': task_id}).json(), len, task_id
        )
    return cast(Document, found[0])


def start_from_form(page: Page, task_name: str, task_data: str, robot_id: str = '') -> str:
    """Start a task with the page's form (on `robot_id`, or any robot); its task id."""
    page.fill('#start-task', task_name)
    page.select_option('#start-robot', robot_id)
    page.fill('#start-data', task_data)
    with page.expect_response('**/start') as answer:
        page.click('#start-button')
    assert answer.value.status == 202, answer.value.text()
    return str(answer.value.json()['task_id'])


def test_any_robot_lands_on_the_free_one_a_banner_confirms_and_stop_all_reaches_every_robot(
    two_demo_robots: None,
    console: ConsoleProcess,
    blank_page: Page,
    start_robot_on: Callable[..., SimulatedRobot],
) -> None:
    start_robot_on('robot3').go_offline()
    page = open_page(blank_page, console, OPERATOR)
    for robot_id in ('robot1', 'robot2'):
        expect(card(page, robot_id)).to_have_attribute('data-task-manager', 'connected')
        expect(card(page, robot_id).locator('.connection-state')).to_have_text('ONLINE')
    expect(card(page, 'robot3').locator('.connection-state')).to_have_text('OFFLINE')
    expect(page.locator(f'#declared-tasks option[value="{NAVIGATE}"]')).to_have_count(1)

    far = start_from_form(page, NAVIGATE, '{"x": 50.0, "y": 0.0}', 'robot1')
    expect(card(page, 'robot1').locator('.active-task')).to_have_attribute('data-task-id', far)
    near = start_from_form(page, NAVIGATE, '{"x": 0.3, "y": 0.0}')
    answer = page.locator('#start-answer')
    expect(answer).to_have_attribute('data-robot-id', 'robot2')
    expect(answer).to_contain_text('robot2 is ONLINE')
    expect(answer).to_contain_text(f'robot1 (its resources for {NAVIGATE} are busy)')
    expect(answer).to_contain_text('robot3 (OFFLINE)')
    near_row = page.locator(f'#history tbody tr[data-task-id="{near}"]')
    expect(near_row).to_have_attribute('data-robot-id', 'robot2')
    expect(near_row).to_contain_text('DONE')

    tray = start_from_form(
        page, 'system/confirm', '{"prompt": "Load the tray", "timeout_sec": 120}', 'robot2'
    )
    item = page.locator('#confirmations .confirmation[data-robot-id="robot2"]')
    expect(item).to_have_attribute('data-task-id', tray)
    expect(item.locator('.confirm-prompt')).to_have_text('Load the tray')
    if os.environ.get(SCREENSHOT_ASKED):
        page.screenshot(path=str(SCREENSHOT), full_page=True)
    item.locator('.confirm-comment').fill('loaded')
    item.locator('button.confirm').click()
    expect(page.locator('#message')).to_contain_text(f'Confirmed {tray} on robot2 (by CLOUD')
    expect(page.locator('#confirmations')).to_be_hidden()
    confirmed = stored(console, tray)

    page.click('#stop-all')
    answers = page.locator('#stop-answers .stop-answer')
    expect(answers).to_have_count(3)
    expect(page.locator('#message')).to_have_text('STOP ALL: 2 of 3 robots stopped')
    far_end = stored(console, far)

    assert (confirmed['robot_id'], confirmed['status']) == ('robot2', 'DONE')
    assert (confirmed['result']['outcome'], confirmed['result']['comment']) == (
        'confirmed',
        'loaded',
    )
    assert [answers.nth(n).get_attribute('data-ok') for n in range(3)] == ['true', 'true', 'false']
    expect(page.locator('#stop-answers [data-robot-id="robot3"]')).to_contain_text('robot_offline')
    assert (far_end['robot_id'], far_end['status']) == ('robot1', 'CANCELED')
