"""The text fields that name a request (task id, task name, source): what is refused, and
how such text goes into a log line.

Control characters (a newline forges a log line; NUL is cut short by ROS, so that
`camera/take_photo\\x00junk` would run the photo task) and the characters that reorder text
on screen (right-to-left overrides and isolates: an id shown reversed on a dashboard) are
refused in every one of them, and so is an id or source longer than MAX_LENGTH.
"""

import re
import unicodedata

from task_manager.core.bounds import TEXT_MAX_CHARACTERS

MAX_LENGTH = TEXT_MAX_CHARACTERS
"""Characters an id or a source may have (a UUID has 36)."""
LOG_LENGTH = 120
"""Characters of a refused value that its log line shows."""
# Unicode's bidirectional formatting characters: embeddings, overrides, isolates and marks.
BIDI_CONTROLS = frozenset(
    '\u061c\u200e\u200f\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069'
)
REFUSED = re.compile(f'[\x00-\x1f\x7f-\x9f{"".join(sorted(BIDI_CONTROLS))}]')
"""What is_refused_character refuses (Unicode's Cc is U+0000-U+001F and U+007F-U+009F), found
in one pass in C: most texts have none, and a check character by character is slow."""
REQUEST_FIELDS = ('task_id', 'task_name', 'source')


def is_refused_character(character: str) -> bool:
    """A control character (Unicode category Cc) or a bidirectional formatting character."""
    return character in BIDI_CONTROLS or unicodedata.category(character) == 'Cc'


def text_problem(field: str, text: str) -> str | None:
    """Why `text` may not be the request's `field` (one of REQUEST_FIELDS); None if it may."""
    found = REFUSED.search(text)
    if found is not None:
        return (
            f'{field} contains the character U+{ord(found.group()):04X} at position '
            f'{found.start()}; ids, task names and sources may not contain control characters '
            'or characters that reorder text (right-to-left overrides)'
        )
    if len(text) > MAX_LENGTH:
        return f'{field} has {len(text)} characters; at most {MAX_LENGTH} are allowed'
    return None


def request_problem(task_id: str, task_name: str, source: str) -> str | None:
    """The first problem of a request's naming fields (see text_problem); None if none."""
    values = dict(zip(REQUEST_FIELDS, (task_id, task_name, source), strict=True))
    return next(
        (problem for field, text in values.items() if (problem := text_problem(field, text))),
        None,
    )


def loggable(text: str, limit: int = LOG_LENGTH) -> str:
    """`text` safe for one log line: refused characters escaped, cut after `limit` characters."""
    shown = ''.join(f'\\u{ord(c):04x}' if is_refused_character(c) else c for c in text[:limit])
    return shown if len(text) <= limit else f'{shown}... ({len(text)} characters)'
