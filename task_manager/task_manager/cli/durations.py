"""Spans of time as taskctl takes them: `45s`, `30m`, `2h`, `1d`, `1h30m`."""

import re
from datetime import timedelta

# key: unit letter, value: seconds in one
UNIT_SECONDS = {'s': 1, 'm': 60, 'h': 3600, 'd': 86400, 'w': 7 * 86400}
_PART = re.compile(r'(\d+(?:\.\d+)?)([smhdw])')
_WHOLE = re.compile(rf'(?:{_PART.pattern})+')


def parse_span(text: str) -> timedelta:
    """`2h` -> 2 hours; raises ValueError saying what is allowed."""
    compact = text.strip().lower()
    if not _WHOLE.fullmatch(compact):
        raise ValueError(
            f'{text!r} is not a span of time; use a number and a unit '
            '(s, m, h, d or w), e.g. 45s, 30m, 2h, 1d, 1h30m'
        )
    seconds = sum(float(n) * UNIT_SECONDS[unit] for n, unit in _PART.findall(compact))
    return timedelta(seconds=seconds)
