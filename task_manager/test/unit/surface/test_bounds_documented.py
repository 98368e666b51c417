"""Every bound of core/bounds.py is listed in the docs, by its name: docs/security.md lists
the Task Manager's, docs/vda5050.md the VDA 5050 adapter's."""

from pathlib import Path

import pytest

from task_manager.core import bounds

DOCS = Path(__file__).resolve().parents[4] / 'docs'


def _bounds(prefix: str, exclude: bool) -> list[str]:
    """The module's bounds (its numbers and NumberBounds in capitals) that start with `prefix`,
    or those that do not."""
    names = [
        name
        for name, value in vars(bounds).items()
        if name.isupper() and isinstance(value, int | float | bounds.NumberBound)
    ]
    return [name for name in names if name.startswith(prefix) is not exclude]


@pytest.mark.parametrize(
    ('page', 'names'),
    [
        ('security.md', _bounds('VDA5050_', exclude=True)),
        ('vda5050.md', _bounds('VDA5050_', exclude=False)),
    ],
)
def test_every_bound_is_listed_by_name(page: str, names: list[str]) -> None:
    text = (DOCS / page).read_text()
    assert names, 'no bounds found'
    missing = [name for name in names if f'`{name}`' not in text]
    assert missing == [], f'{page} does not list {missing}'
