"""Every pending timeout on one clock: the node arms one timer for the earliest of them."""

import heapq
import itertools
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field

# cleared entries kept beyond as many as the live ones before they are dropped at once
_SPARE_CLEARED = 64


@dataclass(order=True)
class _Entry:
    at: float
    order: int
    key: Hashable = field(compare=False)
    action: Callable[[], None] = field(compare=False)
    live: bool = field(default=True, compare=False)


class Deadlines:
    """Actions due at given times, by key; setting a key again replaces its deadline."""

    def __init__(self) -> None:
        self._heap: list[_Entry] = []
        self._by_key: dict[Hashable, _Entry] = {}
        self._order = itertools.count()

    def __len__(self) -> int:
        return len(self._by_key)

    def set(self, key: Hashable, at: float, action: Callable[[], None]) -> None:
        """Run `action` once `at` has come, unless the key is cleared or set again first."""
        self.clear(key)
        entry = _Entry(at, next(self._order), key, action)
        self._by_key[key] = entry
        heapq.heappush(self._heap, entry)

    def clear(self, key: Hashable) -> None:
        entry = self._by_key.pop(key, None)
        if entry is not None:
            entry.live = False
            if len(self._heap) > 2 * len(self._by_key) + _SPARE_CLEARED:
                self._drop_cleared()

    def heap_size(self) -> int:
        """Entries kept, the cleared ones not yet dropped included (for tests)."""
        return len(self._heap)

    def _drop_cleared(self) -> None:
        """Drop the cleared entries at once: a deadline cleared long before it is due (a
        bounded wait that ended early) would otherwise be kept until then."""
        self._heap = [entry for entry in self._heap if entry.live]
        heapq.heapify(self._heap)

    def next_at(self) -> float | None:
        """When the earliest pending deadline is due; None when there is none."""
        while self._heap and not self._heap[0].live:
            heapq.heappop(self._heap)
        return self._heap[0].at if self._heap else None

    def pop_due(self, now: float) -> list[Callable[[], None]]:
        """The actions due by `now`, earliest first; they are forgotten."""
        due = []
        while (at := self.next_at()) is not None and at <= now:
            entry = heapq.heappop(self._heap)
            del self._by_key[entry.key]
            due.append(entry.action)
        return due
