"""What a request may ask of the admission, beside its declaration's defaults."""

from dataclasses import dataclass
from enum import StrEnum


class OnConflict(StrEnum):
    """What a task does when a resource it needs is held by another task."""

    PREEMPT = 'preempt'
    """Cancel the holders (if its priority is at least theirs), then start: the original's rule."""
    QUEUE = 'queue'
    """Wait until the resources are free; the queue is served by priority, then arrival."""
    REJECT = 'reject'
    """End at once, ERROR / resource_busy."""


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
        for name in ('timeout_sec', 'queue_timeout_sec', 'feedback_timeout_sec'):
            value = getattr(self, name)
            if value is not None and not 0 <= value < float('inf'):
                return f'{name} must be a finite number of seconds >= 0, got {value!r}'
        return ''
