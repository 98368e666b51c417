"""The dashboard in a real headless Chromium (Debian's), against a real gateway and node.

Playwright drives the browser at /usr/bin/chromium; it never downloads one.
"""

import shutil
from collections.abc import Callable, Iterator

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect, sync_playwright

from task_manager.testing.gateway import TIMEOUT_SEC, Robot
from task_manager_web.testing import GatewayProcess

pytestmark = pytest.mark.ros

CHROMIUM = shutil.which('chromium') or '/usr/bin/chromium'
# No background connections: this machine's network is closed, and the test needs none.
CHROMIUM_ARGS = [
    '--no-sandbox',
    '--disable-gpu',
    '--disable-quic',
    '--no-first-run',
    '--disable-background-networking',
    '--disable-component-update',
    '--disable-sync',
]
EXPECT_TIMEOUT_MS = int(TIMEOUT_SEC * 1000)


@pytest.fixture(scope='module')
def browser() -> Iterator[Browser]:
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield browser
        browser.close()


@pytest.fixture
def page(browser: Browser, robot: Robot, gateway: GatewayProcess) -> Iterator[Page]:
    """The dashboard, opened with the link the gateway printed, once it shows 'connected'."""
    expect.set_options(timeout=EXPECT_TIMEOUT_MS)
    context = browser.new_context(viewport={'width': 1280, 'height': 900})
    page = context.new_page()
    errors = watch_errors(page)
    page.goto(f'{gateway.url}/?token={gateway.token}')
    expect(page.locator('#connection')).to_have_text('connected')
    yield page
    context.close()
    assert not errors, errors


def watch_errors(page: Page) -> list[str]:
    """The page's script errors and what its Content-Security-Policy refused, as they come."""
    errors: list[str] = []
    page.on('pageerror', lambda error: errors.append(str(error)))
    page.on(
        'console',
        lambda message: (
            errors.append(message.text) if 'Content Security Policy' in message.text else None
        ),
    )
    return errors


@pytest.fixture
def api(gateway: GatewayProcess) -> Iterator[httpx.Client]:
    headers = {'Authorization': f'Bearer {gateway.token}'}
    with httpx.Client(base_url=gateway.url, headers=headers, timeout=TIMEOUT_SEC) as client:
        yield client


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
    browser: Browser, gateway: GatewayProcess
) -> None:
    expect.set_options(timeout=EXPECT_TIMEOUT_MS)
    context = browser.new_context()
    page = context.new_page()
    errors = watch_errors(page)

    page.goto(f'{gateway.url}/docs')

    expect(page.locator('#swagger-ui')).to_contain_text('/api/tasks/start')
    page.locator('.opblock-summary', has_text='/api/tasks/start').click()  # its body's schema
    expect(page.locator('.opblock-body').first).to_contain_text('task_name')
    expect(page.locator('.models')).to_contain_text('StartTask')
    context.close()
    assert not errors, errors
