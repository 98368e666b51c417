"""A page of the history as the gateway answers it, JSON or CSV, of at most `max_bytes`.

A page that would be larger is refused as MQTT refuses a reply over its message size: 422
`reply_too_large`, naming `limit` and how many of the tasks asked for would fit, so that the
caller asks for that many and pages on. Nothing is cut silently: a page either holds every
task asked for or none.
"""

from dataclasses import dataclass
from typing import Any

from fastapi import Response

from task_manager.core.text.json_text import compact_json
from task_manager_web.errors import ApiError
from task_manager_web.history.csv_export import COLUMNS, csv_lines

JSON_TYPE = 'application/json'
CSV_NAME = 'task_history.csv'
PAGING = 'page on with after_sequence (oldest_first=true) or until'
"""How to ask for the next page, in the refusal of a page too large (the gateway's history)."""


@dataclass(frozen=True)
class PageFormat:
    """What a history's pages hold besides their tasks: the CSV's columns and file name, and
    how to page on (the web gateway's by default; the fleet console's have `robot_id`)."""

    columns: tuple[str, ...] = COLUMNS
    csv_name: str = CSV_NAME
    paging: str = PAGING


def history_page(
    tasks: list[dict[str, Any]], as_csv: bool, max_bytes: int, page: PageFormat = PageFormat()
) -> Response:
    """Task documents as a JSON array, or CSV with a header line; ApiError if over max_bytes."""
    if as_csv:
        header, *lines = csv_lines(tasks, page.columns)
        sizes = [len(line.encode()) for line in lines]
        _check(sizes, len(header.encode()), max_bytes, page.paging)
        disposition = {'Content-Disposition': f'attachment; filename="{page.csv_name}"'}
        return Response(header + ''.join(lines), media_type='text/csv', headers=disposition)
    documents = [compact_json(task) for task in tasks]
    sizes = [len(document.encode()) + 1 for document in documents]  # and a comma, or ]
    _check(sizes, 1, max_bytes, page.paging)
    return Response(f'[{",".join(documents)}]', media_type=JSON_TYPE)


def _check(sizes: list[int], overhead: int, max_bytes: int, paging: str) -> None:
    total = overhead + sum(sizes)
    if total <= max_bytes:
        return
    room, fit = max_bytes - overhead, 0
    for size in sizes:
        room -= size
        if room < 0:
            break
        fit += 1
    raise ApiError(
        422,
        'reply_too_large',
        f'the answer ({len(sizes)} tasks) would be {total} bytes; at most {max_bytes} are '
        f'answered: ask for fewer (limit; the first {fit} of these fit), and {paging}',
        'limit',
    )
