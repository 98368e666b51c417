"""The operator's controls on the dashboard, in a real headless Chromium against a real gateway
and node: pause and resume, the schedules panel, confirmations waiting in the banner, and the
controls each role is offered."""

from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import pytest
from playwright.sync_api import Locator, Page, expect

from task_manager.testing.gateway import TIMEOUT_SEC, Robot, wait_until
from task_manager_web.testing import GatewayProcess, HeldRead

pytestmark = pytest.mark.ros

FIB = {'task_name': 'fib', 'task_data': {'order': 1}}
# key: role, value: its token in the token file of `roles_gateway`
TOKENS = {
    'viewer': 'viewer-token-0123456789',
    'operator': 'operator-token-0123456789',
    'admin': 'admin-token-0123456789',
}


@pytest.fixture
def roles_gateway(tmp_path: Path) -> Iterator[GatewayProcess]:
    """A gateway with a viewer (victor), an operator (alice) and an admin token."""
    token_file = tmp_path / 'roles'
    token_file.write_text(
        f'viewer {TOKENS["viewer"]} victor\n'
        f'operator {TOKENS["operator"]} alice\n'
        f'admin {TOKENS["admin"]}\n'
    )
    gateway = GatewayProcess(token_file)
    yield gateway
    assert gateway.stop() == 0, '\n'.join(gateway.log_lines)


def node_status(api: httpx.Client, task_id: str) -> str:
    """The task's status as the node has it (the gateway asks it)."""
    response = api.get(f'/api/tasks/{task_id}')
    assert response.status_code == 200, response.text
    return str(response.json()['status'])


def test_a_mission_is_paused_and_resumed_from_the_page(
    page: Page, robot: Robot, api: httpx.Client
) -> None:
    mission = {'subtasks': [FIB, FIB], 'task_id': 'm-1'}
    assert api.post('/api/missions', json=mission).status_code == 202
    robot.fib.wait_for_goals(1, TIMEOUT_SEC)
    plain = {**FIB, 'task_id': 'plain'}  # fib is declared pause: none
    assert api.post('/api/tasks/start', json=plain).status_code == 202
    robot.fib.wait_for_goals(2, TIMEOUT_SEC)
    row = page.locator('#active tbody tr[data-task-id="m-1"]')
    card = page.locator('.mission[data-mission-id="m-1"]')
    expect(page.locator('#active tbody tr[data-task-id="plain"]')).to_contain_text('IN_PROGRESS')
    expect(page.locator('#active tbody tr[data-task-id="plain"] button.pause')).to_have_count(0)

    row.locator('button.pause').click()

    expect(row.locator('.badge')).to_have_text('PAUSED')
    expect(card.locator('.mission-title .badge')).to_have_text('PAUSED')
    expect(page.locator('#message')).to_have_text('m-1 paused')
    assert node_status(api, 'm-1') == 'PAUSED'
    expect(row.locator('button.pause')).to_have_count(0)
    expect(card.locator('.step').nth(0)).to_have_attribute('data-state', 'running')  # goes on

    card.locator('button.resume').click()

    expect(row.locator('.badge')).to_have_text('IN_PROGRESS')
    expect(page.locator('#message')).to_have_text('m-1 resumed')
    assert node_status(api, 'm-1') == 'IN_PROGRESS'
    expect(row.locator('button.pause')).to_be_visible()
    for goal in robot.fib.wait_for_goals(2, TIMEOUT_SEC):
        goal.succeed()
    robot.fib.wait_for_goals(3, TIMEOUT_SEC)[2].succeed()  # the mission goes on
    expect(card.locator('.mission-title .badge')).to_have_text('DONE')


def test_a_schedule_is_added_from_the_start_form_then_disabled_and_removed(
    page: Page, api: httpx.Client
) -> None:
    page.select_option('#task-select', 'fib')
    page.fill('[data-field="order"]', '4')
    page.fill('#start-priority', '3')
    page.select_option('#start-when', 'cron')
    expect(page.locator('#start-button')).to_have_text('Schedule')
    page.fill('#when-cron', '0 2 * * *')
    page.fill('#when-time-zone', 'Europe/Paris')
    page.fill('#when-schedule-id', 'nightly')

    page.click('#start-button')

    expect(page.locator('#message')).to_contain_text('Scheduled fib: nightly, next run ')
    row = page.locator('#schedules tbody tr[data-schedule-id="nightly"]')
    expect(row).to_contain_text('Europe/Paris')
    expect(row.locator('.next-run .relative')).to_contain_text('in ')
    expect(row.locator('.last-run')).to_have_text('not yet')
    expect(row.locator('.counts')).to_have_text('0 runs, 0 missed')
    (schedule,) = api.get('/api/schedules').json()
    assert (schedule['task_name'], schedule['task_data'], schedule['options']) == (
        'fib',
        {'order': 4},
        {'priority': 3},
    )
    assert (schedule['cron'], schedule['time_zone'], schedule['created_by']) == (
        '0 2 * * *',
        'Europe/Paris',
        'WEB',
    )

    row.locator('button.toggle').click()

    expect(row).to_have_attribute('data-enabled', 'false')
    expect(row.locator('.next-run')).to_have_text('disabled')
    expect(row.locator('button.toggle')).to_have_text('Enable')
    assert api.get('/api/schedules').json()[0]['enabled'] is False

    row.locator('button.remove').click()
    expect(page.locator('#remove-dialog')).to_contain_text('nightly')
    page.click('#remove-keep')  # asked again: kept
    expect(page.locator('#remove-dialog')).to_be_hidden()
    assert len(api.get('/api/schedules').json()) == 1
    row.locator('button.remove').click()
    page.click('#remove-yes')

    expect(row).to_have_count(0)
    expect(page.locator('#schedules-empty')).to_be_visible()
    assert api.get('/api/schedules').json() == []


def test_the_schedules_panel_follows_a_run_from_its_events(
    page: Page, robot: Robot, api: httpx.Client
) -> None:
    once = {**FIB, 'schedule_id': 'soon', 'delay_sec': 1}
    assert api.post('/api/schedules', json=once).json()['scheduled']  # from another door
    row = page.locator('#schedules tbody tr[data-schedule-id="soon"]')
    expect(row.locator('.last-run')).to_have_text('not yet')

    (goal,) = robot.fib.wait_for_goals(1, TIMEOUT_SEC)
    expect(row.locator('.counts')).to_have_text('1 run, 0 missed')
    goal.succeed()

    # the panel is read again on the run's events, not on a timer (a minute)
    expect(row.locator('.last-run .badge')).to_have_text('DONE')
    expect(row.locator('.next-run')).to_have_text('none to come')


def test_an_older_read_of_the_schedules_answered_last_does_not_hide_a_newer_schedule(
    blank_page: Page, open_holding_first_read: Callable[[str], HeldRead], api: httpx.Client
) -> None:
    page = blank_page
    first_read = open_holding_first_read('**/api/schedules')
    older = first_read.fetch()  # no schedule yet
    nightly = {**FIB, 'schedule_id': 'nightly', 'cron': '0 2 * * *'}
    assert api.post('/api/schedules', json=nightly).json()['scheduled']  # from another door
    row = page.locator('#schedules tbody tr[data-schedule-id="nightly"]')
    expect(row).to_have_count(1)  # read again on the change's event

    first_read.answer(older)

    expect(row).to_have_count(1)


def test_a_waiting_step_is_confirmed_from_the_banner_and_its_mission_goes_on(
    page: Page, robot: Robot, api: httpx.Client
) -> None:
    confirm = {
        'task_name': 'system/confirm',
        'task_data': {'prompt': 'Load the tray, then confirm', 'timeout_sec': 600},
        'task_id': 'tray',
    }
    mission = {'subtasks': [FIB, confirm, FIB], 'task_id': 'm-c'}
    assert api.post('/api/missions', json=mission).status_code == 202
    banner = page.locator('#confirmations .confirmation[data-task-id="tray"]')
    expect(page.locator('#confirmations')).to_be_hidden()
    robot.fib.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()

    expect(banner.locator('.confirm-prompt')).to_have_text('Load the tray, then confirm')
    expect(banner.locator('.confirm-where')).to_have_text('step 2 of 3 of mission m-c')
    expect(banner.locator('.countdown')).to_contain_text(' min ')
    expect(page).to_have_title('(1) waiting for confirmation · Task Manager')
    assert node_status(api, 'tray') == 'IN_PROGRESS'
    banner.locator('.confirm-comment').fill('tray loaded')
    banner.locator('button.confirm').click()

    expect(page.locator('#message')).to_have_text('Confirmed tray (by WEB)')
    expect(banner).to_have_count(0)
    expect(page).to_have_title('Task Manager')
    robot.fib.wait_for_goals(2, TIMEOUT_SEC)[1].succeed()  # the mission goes on
    mission_card = page.locator('.mission[data-mission-id="m-c"]')
    expect(mission_card.locator('.mission-title .badge')).to_have_text('DONE')
    answered = api.get('/api/tasks/tray').json()
    assert (answered['status'], answered['result']) == (
        'DONE',
        {'confirmed': True, 'by': 'WEB', 'comment': 'tray loaded', 'outcome': 'confirmed'},
    )


def test_a_confirmation_rejected_from_the_banner_ends_error(page: Page, api: httpx.Client) -> None:
    confirm = {'task_name': 'system/confirm', 'task_data': {'prompt': 'Door open?'}}
    assert api.post('/api/tasks/start', json={**confirm, 'task_id': 'door'}).status_code == 202
    banner = page.locator('#confirmations .confirmation[data-task-id="door"]')
    expect(banner.locator('.confirm-where')).to_have_text('task door')

    banner.locator('button.reject').click()

    expect(page.locator('#message')).to_have_text('Rejected door (by WEB)')
    expect(banner).to_have_count(0)
    answered = api.get('/api/tasks/door').json()
    assert (answered['status'], answered['error_code'], answered['result']['outcome']) == (
        'ERROR',
        'rejected',
        'rejected',
    )


def open_as(page: Page, gateway: GatewayProcess, role: str) -> None:
    page.goto(f'{gateway.url}/?token={TOKENS[role]}')
    expect(page.locator('#connection')).to_have_text('connected')
    expect(page.locator('body')).to_have_attribute('data-role', role)


def expect_shown(locators: list[Locator], shown: bool) -> None:
    for locator in locators:
        if shown:
            expect(locator).to_be_visible()
        else:
            expect(locator).to_be_hidden()


def test_each_role_is_offered_only_the_controls_it_may_use(
    blank_page: Page, robot: Robot, roles_gateway: GatewayProcess
) -> None:
    admin = {'Authorization': f'Bearer {TOKENS["admin"]}'}
    with httpx.Client(base_url=roles_gateway.url, headers=admin, timeout=TIMEOUT_SEC) as api:
        wait_until(lambda: api.get('/api/health').json()['connected'], 'gateway connected')
        assert api.post('/api/missions', json={'subtasks': [FIB], 'task_id': 'm-1'}).is_success
        nightly = {**FIB, 'schedule_id': 'nightly', 'cron': '0 2 * * *'}
        assert api.post('/api/schedules', json=nightly).json()['scheduled']
    robot.fib.wait_for_goals(1, TIMEOUT_SEC)
    page = blank_page
    mission_row = page.locator('#active tbody tr[data-task-id="m-1"]')
    schedule_row = page.locator('#schedules tbody tr[data-schedule-id="nightly"]')
    operator_controls = [
        page.locator('#stop'),
        page.locator('#start-form'),
        mission_row.locator('button.pause'),
        mission_row.locator('button.cancel'),
    ]
    admin_controls = [
        page.locator('#start-priority'),
        page.locator('#start-when'),
        mission_row.locator('button.reprioritize'),
        schedule_row.locator('button.toggle'),
        schedule_row.locator('button.remove'),
    ]

    open_as(page, roles_gateway, 'viewer')

    expect(page.locator('#who')).to_have_text('victor (viewer)')
    expect(mission_row).to_contain_text('IN_PROGRESS')
    expect(schedule_row).to_contain_text('0 2 * * *')
    expect_shown(operator_controls + admin_controls, False)

    open_as(page, roles_gateway, 'operator')

    expect(page.locator('#who')).to_have_text('alice (operator)')
    expect_shown(operator_controls, True)
    expect_shown(admin_controls, False)

    open_as(page, roles_gateway, 'admin')

    expect_shown(operator_controls + admin_controls, True)
    robot.fib.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
