"""The history's CSV export, without a node: no cell a spreadsheet would run as a formula."""

import csv
import io
from typing import Any

import pytest

from task_manager_web.history.csv_export import history_csv


def exported(**task: Any) -> dict[str, str]:
    (row,) = csv.DictReader(io.StringIO(history_csv([task]), newline=''))
    return row


@pytest.mark.parametrize(
    'text', ['=HYPERLINK("http://x","y")', '+1+cmd|calc', '-2+3', '@SUM(A1)', '\tx', '\r=1']
)
def test_text_a_spreadsheet_would_run_is_quoted(text: str) -> None:
    row = exported(task_id=text, task_name=text, source=text, error_message=text)

    assert [row[c] for c in ('task_id', 'task_name', 'source', 'error_message')] == [f"'{text}"] * 4


def test_other_text_numbers_and_results_are_written_as_they_are() -> None:
    row = exported(
        task_id='a=b',
        task_name='nav/go',
        sequence=3,
        duration_sec=-0.5,
        result={'x': '=1'},
        mission_id=None,
    )

    assert (row['task_id'], row['task_name'], row['sequence']) == ('a=b', 'nav/go', '3')
    assert (row['duration_sec'], row['result'], row['mission_id']) == ('-0.5', '{"x":"=1"}', '')
