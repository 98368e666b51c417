"""system/confirm decided: its goal checked, an answer checked, and how it ends.

A confirmation waits for an operator's answer (through /task_manager/confirm_task) until its
timeout: confirmed ends it DONE, rejected ERROR (`rejected`), the timeout ERROR (`timeout`) or,
with `on_timeout: continue`, DONE. Its result says who answered and from which door (`by`, the
answer's source), the answer's comment and the outcome.
"""

from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from task_manager.core.bounds import SECONDS
from task_manager.core.names import CONFIRM
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.core.task import TaskEnd
from task_manager.core.text.request_text import is_refused_character, text_problem

DEFAULT_TIMEOUT_SEC = 600.0
TEXT_MAX_LENGTH = 1000
"""Characters a prompt or an answer's comment may have."""


class OnTimeout(StrEnum):
    """What a confirmation that nobody answered in time ends with."""

    FAIL = 'fail'
    """ERROR, error code `timeout` (the default): a mission stops at it."""
    CONTINUE = 'continue'
    """DONE, outcome `timed_out`: a mission goes on."""


class Outcome(StrEnum):
    """How a confirmation was settled (its result's `outcome`)."""

    CONFIRMED = 'confirmed'
    """Someone confirmed it."""
    REJECTED = 'rejected'
    """Someone rejected it."""
    TIMED_OUT = 'timed_out'
    """Nobody answered within its timeout_sec."""


class AnswerRefusal(StrEnum):
    """Why an answer was not taken (ConfirmTask's error_code)."""

    NOT_FOUND = 'not_found'
    """No task has the id: neither active nor in the history."""
    NOT_WAITING = 'not_waiting'
    """The task is not a system/confirm waiting for its answer."""
    INVALID_REQUEST = 'invalid_request'
    """The answer's comment or source has refused characters, or is too long or empty."""


@dataclass(frozen=True)
class ConfirmGoal:
    """A checked system/confirm goal."""

    prompt: str
    timeout_sec: float = DEFAULT_TIMEOUT_SEC
    on_timeout: OnTimeout = OnTimeout.FAIL


@dataclass(frozen=True)
class Answer:
    """An operator's answer to a waiting confirmation."""

    reject: bool
    by: str
    """Who answered and from which door (the request's source: WEB:alice, taskctl, ...)."""
    comment: str = ''


def free_text_problem(field: str, text: str) -> str | None:
    """Why `text` may not be a prompt or comment: refused characters (a newline forges a log
    line) or longer than TEXT_MAX_LENGTH; None if it may."""
    for position, character in enumerate(text):
        if is_refused_character(character):
            return (
                f'{field} contains the character U+{ord(character):04X} at position {position}; '
                'it may not contain control characters (newlines included) or characters that '
                'reorder text (right-to-left overrides)'
            )
    if len(text) > TEXT_MAX_LENGTH:
        return f'{field} has {len(text)} characters; at most {TEXT_MAX_LENGTH} are allowed'
    return None


def goal_problem(prompt: str, timeout_sec: float, on_timeout: str) -> tuple[str, str] | None:
    """The first field of a system/confirm goal that is wrong and why; None if none is."""
    if not prompt.strip():
        return 'prompt', 'is required: the question the operator answers'
    if problem := free_text_problem('prompt', prompt):
        return 'prompt', problem
    if timeout_sec <= 0 or SECONDS.problem('timeout_sec', timeout_sec):
        return (
            'timeout_sec',
            f'must be a number of seconds > 0 and <= {SECONDS.high:g}, got {timeout_sec}',
        )
    if on_timeout not in tuple(OnTimeout):
        allowed = ', '.join(repr(value.value) for value in OnTimeout)
        return 'on_timeout', f'must be one of {allowed}, got {on_timeout!r}'
    return None


def answer_problem(answer: Answer) -> str | None:
    """Why an answer cannot be taken for its text (its comment or source); None if it can."""
    if not answer.by:
        return 'source is empty: an answer says who gives it (e.g. taskctl, WEB:alice)'
    return text_problem('source', answer.by) or free_text_problem('comment', answer.comment)


def not_waiting_reason(task_id: str, task_name: str, status: str) -> str:
    """Why the task `task_id` (of `task_name`, now `status`) takes no answer."""
    if task_name != CONFIRM:
        return (
            f'task {task_id!r} is a {task_name} task, not {CONFIRM}; only a waiting '
            f'{CONFIRM} takes an answer'
        )
    if TaskStatus(status).is_final:
        return f'task {task_id!r} ({CONFIRM}) has ended {status}; it takes no more answers'
    if status == TaskStatus.IN_PROGRESS:
        return f'task {task_id!r} ({CONFIRM}) is ending: it has just been answered or timed out'
    return f'task {task_id!r} ({CONFIRM}) is {status}, not waiting for an answer'


def not_found_reason(task_id: str) -> str:
    """Why an answer to an id nobody knows is not taken."""
    return f'no task {task_id!r}: none is active, and none is in the history'


def _result(outcome: Outcome, answer: Answer | None = None) -> dict[str, Any]:
    return {
        'confirmed': outcome is Outcome.CONFIRMED,
        'by': answer.by if answer else '',
        'comment': answer.comment if answer else '',
        'outcome': str(outcome),
    }


def end_of_answer(answer: Answer) -> TaskEnd:
    """Confirmed: DONE; rejected: ERROR, `rejected`; the result names who answered."""
    if answer.reject:
        return TaskEnd(TaskStatus.ERROR, _result(Outcome.REJECTED, answer), ErrorCode.REJECTED)
    return TaskEnd(TaskStatus.DONE, _result(Outcome.CONFIRMED, answer))


def end_of_timeout(goal: ConfirmGoal) -> TaskEnd:
    """Nobody answered in time: ERROR, `timeout`, or DONE with `on_timeout: continue`."""
    if goal.on_timeout is OnTimeout.CONTINUE:
        return TaskEnd(TaskStatus.DONE, _result(Outcome.TIMED_OUT))
    return TaskEnd(TaskStatus.ERROR, _result(Outcome.TIMED_OUT), ErrorCode.TIMEOUT)


def feedback(goal: ConfirmGoal, elapsed_sec: float) -> dict[str, Any]:
    """The feedback of a waiting confirmation: its prompt and the seconds left."""
    return {'prompt': goal.prompt, 'remaining_sec': max(0.0, goal.timeout_sec - elapsed_sec)}
