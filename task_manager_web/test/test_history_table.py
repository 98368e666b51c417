"""The dashboard's history table (static/history.js on history_table.js) in Chromium, its reads
answered by the test: a stored end is shown once however its read and its live row meet."""

import mimetypes
from typing import Any

from playwright.sync_api import Page, Route

from task_manager_web.app import STATIC

ORIGIN = 'http://history.test'
TABLE_PAGE = """<!doctype html><form id="history-filters"></form><p id="history-empty"></p>
<table id="history"><tbody></tbody></table><p id="message"></p>"""


def ended(task_id: str, sequence: int) -> dict[str, Any]:
    return {
        'task_id': task_id,
        'task_name': 'drive',
        'source': 'WEB',
        'status': 'DONE',
        'ended': '2026-11-29T02:00:00+00:00',
        'sequence': sequence,
        'result': {},
    }


def table_page(page: Page, stored: list[dict[str, Any]]) -> Page:
    """The history table alone, its module from the package's static folder, every read of
    /api/history answered with `stored`."""

    def answer(route: Route) -> None:
        path = route.request.url.removeprefix(ORIGIN).split('?', 1)[0]
        if path == '/api/history':
            route.fulfill(json=stored)
        elif path == '/':
            route.fulfill(body=TABLE_PAGE, content_type='text/html')
        else:
            file = STATIC / path.removeprefix('/static/')
            route.fulfill(body=file.read_bytes(), content_type=mimetypes.guess_type(file)[0])

    page.route(f'{ORIGIN}/**', answer)
    page.goto(f'{ORIGIN}/')
    return page


def shown_after(page: Page, live: list[dict[str, Any]]) -> list[str]:
    """The rows' task ids once the history was read, then `live` came as tasks ended."""
    return list(
        page.evaluate(
            """async (live) => {
                const history = await import('/static/history.js');
                history.wireHistory();
                await history.loadHistory();
                for (const task of live) history.addHistoryRow(task);
                return [...document.querySelectorAll('#history tbody tr')]
                    .map((row) => row.dataset.taskId);
            }""",
            live,
        )
    )


def test_a_live_row_after_a_read_that_held_it_is_shown_once(blank_page: Page) -> None:
    # the read overtook the task's ENDED event: the gateway answered it from the history,
    # which has the end before the event reaches the page
    page = table_page(blank_page, [ended('drive-1', 1)])

    assert shown_after(page, [ended('drive-1', 1)]) == ['drive-1']


def test_a_task_id_used_again_shows_each_of_its_ends(blank_page: Page) -> None:
    page = table_page(blank_page, [ended('drive-1', 1)])

    assert shown_after(page, [ended('drive-1', 2), ended('drive-1', 2)]) == [
        'drive-1',
        'drive-1',
    ]


def test_the_stored_ends_are_read_into_the_table(blank_page: Page) -> None:
    page = table_page(blank_page, [ended('b', 2), ended('a', 1)])

    assert shown_after(page, []) == ['b', 'a']
    assert page.locator('#history-empty').is_hidden()
