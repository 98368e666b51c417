"""What a request may ask of the admission, beside its declaration's defaults."""

from dataclasses import asdict, dataclass
from enum import StrEnum
from typing import Any

from task_manager.core.bounds import PRIORITY, SECONDS, cut_text


class OnConflict(StrEnum):
    """What a task does when a resource it needs is held by another task."""

    PREEMPT = 'preempt'
    """Cancel the holders (if its priority is at least theirs), then start: the original's rule."""
    QUEUE = 'queue'
    """Wait until the resources are free; the queue is served by priority, then arrival."""
    REJECT = 'reject'
    """End at once, ERROR / resource_busy."""


def parse_on_conflict(text: object) -> OnConflict:
    """An on_conflict as written (any case, spaces around); ValueError says what is allowed."""
    try:
        return OnConflict(str(text).strip().lower())
    except ValueError:
        allowed = ', '.join(mode.value for mode in OnConflict)
        got = cut_text(str(text)) if isinstance(text, str) else text
        raise ValueError(f'on_conflict must be one of {allowed}, got {got!r}') from None


@dataclass(frozen=True)
class RequestOptions:
    """One request's own admission options; None takes the declaration's value."""

    priority: int | None = None
    on_conflict: OnConflict | None = None
    timeout_sec: float | None = None
    queue_timeout_sec: float | None = None
    feedback_timeout_sec: float | None = None
    error: str = ''
    """Why the options as sent could not be read (e.g. an unknown on_conflict)."""

    @property
    def is_empty(self) -> bool:
        return self == RequestOptions()

    def problem(self) -> str:
        """Why these options are unusable; empty when they are fine."""
        if self.error:
            return self.error
        if self.priority is not None and (problem := PRIORITY.problem('priority', self.priority)):
            return problem
        for name in ('timeout_sec', 'queue_timeout_sec', 'feedback_timeout_sec'):
            value = getattr(self, name)
            if value is not None and (problem := SECONDS.problem(name, value)):
                return problem
        return ''

    def to_dict(self) -> dict[str, Any]:
        """The options given, as JSON values (what a schedule keeps)."""
        return {
            name: str(value) if isinstance(value, OnConflict) else value
            for name, value in asdict(self).items()
            if value is not None and name != 'error'
        }

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> 'RequestOptions':
        """The inverse of to_dict; ValueError names a field that is not one of the options."""
        known = {'priority', 'on_conflict', 'timeout_sec', 'queue_timeout_sec',
                 'feedback_timeout_sec'}  # fmt: skip
        if unknown := sorted(set(values) - known):
            raise ValueError(f'unknown options {unknown}; known: {sorted(known)}')
        on_conflict = values.get('on_conflict')
        return cls(**{**values, 'on_conflict': OnConflict(on_conflict) if on_conflict else None})
