"""Which task events go out together on /task_manager/task_event_batches: those of one
executor turn, in order, at most `max_events` of them and `max_bytes` of their text in one
message; an event larger than `max_bytes` by itself goes in a message alone."""

from typing import Generic, TypeVar

T = TypeVar('T')


class EventBatch(Generic[T]):
    """The events gathered for the next message."""

    def __init__(self, max_events: int, max_bytes: int) -> None:
        self.max_events = max_events
        self.max_bytes = max_bytes
        self._events: list[T] = []
        self._bytes = 0

    def __len__(self) -> int:
        return len(self._events)

    def add(self, event: T, size: int) -> list[T]:
        """Add `event` (`size`: its text, as `max_bytes` counts it); the events to send before
        it, when the batch had no room left for it (else [])."""
        full: list[T] = []
        if self._events and (
            len(self._events) >= self.max_events or self._bytes + size > self.max_bytes
        ):
            full = self.take()
        self._events.append(event)
        self._bytes += size
        return full

    def take(self) -> list[T]:
        """The events gathered, oldest first; the batch is empty afterwards."""
        events, self._events, self._bytes = self._events, [], 0
        return events
