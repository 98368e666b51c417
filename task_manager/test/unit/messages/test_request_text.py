"""Ids, task names and sources: control and reordering characters and overlong values are
refused, and whatever is logged of them fits one short line."""

import pytest

from task_manager.core.text.request_text import MAX_LENGTH, loggable, request_problem, text_problem

REFUSED = ['\x00', '\n', '\r', '\t', '\x1b', '\x7f', '\x85', '\u202e', '\u2066', '\u200f']


@pytest.mark.parametrize('character', REFUSED)
def test_control_and_reordering_characters_are_refused_naming_the_field_and_where(
    character: str,
) -> None:
    problem = text_problem('task_id', f'ab{character}c')

    assert problem is not None
    assert problem.startswith(
        f'task_id contains the character U+{ord(character):04X} at position 2'
    )


def test_ordinary_text_in_any_script_passes() -> None:
    for text in ('nav-1', 'navigation/navigate_to_pose', 'Voice control', 'مهمة', '任务', 'é' * 10):
        assert text_problem('source', text) is None


def test_an_overlong_value_is_refused_with_the_limit() -> None:
    assert text_problem('source', 'x' * MAX_LENGTH) is None
    assert text_problem('source', 'x' * (MAX_LENGTH + 1)) == (
        f'source has {MAX_LENGTH + 1} characters; at most {MAX_LENGTH} are allowed'
    )


def test_request_problem_names_the_first_field_at_fault() -> None:
    assert request_problem('id', 'fib', 'CLI') is None
    problem = request_problem('id', 'camera/take_photo\x00junk', 'CLI')
    assert problem is not None and problem.startswith('task_name contains the character U+0000')


def test_loggable_escapes_and_cuts() -> None:
    assert loggable('a\nb\u202ec') == 'a\\u000ab\\u202ec'
    assert loggable('x' * 100_000, limit=10) == 'xxxxxxxxxx... (100000 characters)'
    assert '\n' not in loggable('forged\n[INFO] line' * 50)
