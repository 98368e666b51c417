"""Tests of system/confirm's decisions: its goal and answers checked, and how it ends."""

import math

import pytest

from task_manager.core.confirmation import (
    TEXT_MAX_LENGTH,
    Answer,
    ConfirmGoal,
    OnTimeout,
    answer_problem,
    end_of_answer,
    end_of_timeout,
    feedback,
    goal_problem,
    not_found_reason,
    not_waiting_reason,
)
from task_manager.core.status import ErrorCode, TaskStatus


def test_a_goal_with_a_prompt_and_the_defaults_is_accepted() -> None:
    goal = ConfirmGoal('Load the tray, then confirm')
    assert goal.timeout_sec == 600.0
    assert goal.on_timeout is OnTimeout.FAIL
    assert goal_problem(goal.prompt, goal.timeout_sec, goal.on_timeout) is None
    assert goal_problem('ok?', 0.5, 'continue') is None


@pytest.mark.parametrize(
    ('prompt', 'timeout_sec', 'on_timeout', 'field', 'words'),
    [
        ('', 600.0, 'fail', 'prompt', 'is required'),
        ('   ', 600.0, 'fail', 'prompt', 'is required'),
        ('load\nthe tray', 600.0, 'fail', 'prompt', 'U+000A at position 4'),
        ('load \u202ethe tray', 600.0, 'fail', 'prompt', 'U+202E at position 5'),
        ('x' * (TEXT_MAX_LENGTH + 1), 600.0, 'fail', 'prompt', 'at most 1000'),
        ('ok?', 0.0, 'fail', 'timeout_sec', '> 0 and <= 604800, got 0.0'),
        ('ok?', -1.0, 'fail', 'timeout_sec', '> 0 and <= 604800, got -1.0'),
        ('ok?', math.inf, 'fail', 'timeout_sec', '> 0 and <= 604800, got inf'),
        ('ok?', math.nan, 'fail', 'timeout_sec', '> 0 and <= 604800, got nan'),
        ('ok?', 1e300, 'fail', 'timeout_sec', '> 0 and <= 604800, got 1e+300'),
        ('ok?', 600.0, 'skip', 'on_timeout', "one of 'fail', 'continue', got 'skip'"),
        ('ok?', 600.0, '', 'on_timeout', "got ''"),
    ],
)
def test_a_wrong_goal_names_its_field_and_what_is_allowed(
    prompt: str, timeout_sec: float, on_timeout: str, field: str, words: str
) -> None:
    problem = goal_problem(prompt, timeout_sec, on_timeout)
    assert problem is not None
    assert problem[0] == field
    assert words in problem[1]


def test_a_prompt_of_the_longest_length_is_accepted() -> None:
    assert goal_problem('x' * TEXT_MAX_LENGTH, 1.0, 'fail') is None


def test_confirmed_ends_done_naming_who_answered() -> None:
    end = end_of_answer(Answer(reject=False, by='WEB:alice', comment='tray loaded'))
    assert end.status is TaskStatus.DONE
    assert end.error_code is ErrorCode.NONE
    assert end.result == {
        'confirmed': True,
        'by': 'WEB:alice',
        'comment': 'tray loaded',
        'outcome': 'confirmed',
    }


def test_rejected_ends_error_rejected_naming_who_answered() -> None:
    end = end_of_answer(Answer(reject=True, by='taskctl', comment='tray is broken'))
    assert end.status is TaskStatus.ERROR
    assert end.error_code is ErrorCode.REJECTED
    assert end.result == {
        'confirmed': False,
        'by': 'taskctl',
        'comment': 'tray is broken',
        'outcome': 'rejected',
    }


def test_a_timeout_fails_by_default() -> None:
    end = end_of_timeout(ConfirmGoal('ok?', 1.0))
    assert end.status is TaskStatus.ERROR
    assert end.error_code is ErrorCode.TIMEOUT
    assert end.result == {'confirmed': False, 'by': '', 'comment': '', 'outcome': 'timed_out'}


def test_a_timeout_with_on_timeout_continue_ends_done_timed_out() -> None:
    end = end_of_timeout(ConfirmGoal('ok?', 1.0, OnTimeout.CONTINUE))
    assert end.status is TaskStatus.DONE
    assert end.error_code is ErrorCode.NONE
    assert end.result['outcome'] == 'timed_out'
    assert end.result['confirmed'] is False


def test_an_answer_needs_a_source_and_clean_text() -> None:
    assert answer_problem(Answer(False, 'taskctl')) is None
    assert answer_problem(Answer(True, 'WEB:alice', 'x' * TEXT_MAX_LENGTH)) is None
    assert 'source is empty' in (answer_problem(Answer(False, '')) or '')
    assert 'source contains the character U+0000' in (answer_problem(Answer(False, 'a\0')) or '')
    long_comment = answer_problem(Answer(False, 'taskctl', 'x' * (TEXT_MAX_LENGTH + 1)))
    assert long_comment == 'comment has 1001 characters; at most 1000 are allowed'
    assert 'comment contains the character U+000D' in (
        answer_problem(Answer(False, 'taskctl', 'a\rb')) or ''
    )


def test_the_feedback_counts_down_to_zero() -> None:
    goal = ConfirmGoal('Load the tray', 10.0)
    assert feedback(goal, 0.0) == {'prompt': 'Load the tray', 'remaining_sec': 10.0}
    assert feedback(goal, 2.5)['remaining_sec'] == 7.5
    assert feedback(goal, 12.0)['remaining_sec'] == 0.0


def test_why_a_task_takes_no_answer_says_what_it_is() -> None:
    assert not_waiting_reason('nav-1', 'navigation/navigate', 'IN_PROGRESS') == (
        "task 'nav-1' is a navigation/navigate task, not system/confirm; only a waiting "
        'system/confirm takes an answer'
    )
    assert not_waiting_reason('c-1', 'system/confirm', 'DONE') == (
        "task 'c-1' (system/confirm) has ended DONE; it takes no more answers"
    )
    assert 'is ending' in not_waiting_reason('c-1', 'system/confirm', 'IN_PROGRESS')
    assert 'is QUEUED, not waiting' in not_waiting_reason('c-1', 'system/confirm', 'QUEUED')
    assert not_found_reason('nope') == (
        "no task 'nope': none is active, and none is in the history"
    )
