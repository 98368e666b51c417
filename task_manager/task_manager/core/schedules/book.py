"""Every schedule, its run state, and which are due: one heap for all, so one timer serves them.

The caller sets one timer for `next_due()`, calls `take_due(now)` when it rings, starts (or,
by the overlap policy, skips) each firing, and saves the changed states. `take_due` is also
the catch-up at start: runs missed while the node was down are coalesced into one, or counted
as missed when even the latest of them is later than the schedule's misfire grace.
"""

import dataclasses
import heapq
import json
from collections.abc import Iterator
from dataclasses import dataclass
from enum import StrEnum

from task_manager.core.schedules.schedule import (
    OverlapPolicy,
    ScheduleSpec,
    first_fire_time,
    latest_fire_at_or_before,
    load_fields,
    next_fire_after,
)

_OPTIONAL_NUMBER = (float, int, type(None))
# key: field, value: the JSON types it may hold
_STATE_TYPES: dict[str, tuple[type, ...]] = {
    'enabled': (bool,), 'next_run': _OPTIONAL_NUMBER, 'last_run': _OPTIONAL_NUMBER,
    'last_task_id': (str,), 'last_status': (str,), 'run_count': (int,), 'missed_count': (int,),
    'skipped_count': (int,),
}  # fmt: skip


def run_task_id(schedule_id: str, run_number: int) -> str:
    """The task id of a schedule's run number `run_number` (from 1)."""
    return f'{schedule_id}-run-{run_number}'


def run_source(schedule_id: str) -> str:
    """The source of the tasks that a schedule starts."""
    return f'schedule:{schedule_id}'


@dataclass
class ScheduleState:
    """How a schedule has run and when it runs next; saved with its spec."""

    enabled: bool = True
    next_run: float | None = None
    """None: finished, no more runs. Not used while disabled (enabling recomputes it)."""
    last_run: float | None = None
    """When the last run started."""
    last_task_id: str = ''
    last_status: str = ''
    """'IN_PROGRESS' while the last run runs, then how it ended (e.g. 'DONE')."""
    run_count: int = 0
    """Runs started."""
    missed_count: int = 0
    """Due times that did not run: later than the misfire grace, or coalesced into a later one."""
    skipped_count: int = 0
    """Firings skipped by the overlap policy."""

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), separators=(',', ':'))

    @classmethod
    def from_json(cls, text: str) -> 'ScheduleState':
        """The state stored by to_json; ValueError if this version cannot read it."""
        return cls(**load_fields(text, _STATE_TYPES))


@dataclass(frozen=True)
class Firing:
    """A schedule to run now."""

    schedule_id: str
    due_at: float
    """The due time being run (the latest one when coalesced)."""
    coalesced: int = 0
    """How many earlier due times, not run, this one stands for."""


class RunAction(StrEnum):
    """What to do with a firing, given the previous run of its schedule."""

    START = 'START'
    SKIP = 'SKIP'
    BUFFER = 'BUFFER'
    """Start it when the previous run ends."""
    CANCEL_AND_START = 'CANCEL_AND_START'


def overlap_action(policy: OverlapPolicy, previous_active: bool, one_buffered: bool) -> RunAction:
    """The decision for a firing while the previous run of its schedule may still be active."""
    if not previous_active or policy is OverlapPolicy.ALLOW_ALL:
        return RunAction.START
    if policy is OverlapPolicy.CANCEL_OTHER:
        return RunAction.CANCEL_AND_START
    if policy is OverlapPolicy.BUFFER_ONE and not one_buffered:
        return RunAction.BUFFER
    return RunAction.SKIP


class ScheduleBook:
    """The schedules of one Task Manager and the heap of their next due times.

    The heap holds (time, sequence, id) entries and deletes lazily: an entry counts only while
    it is the schedule's current one (in `_queued`), so a change is one push, not a search.
    States handed out are copies: change them only through the book's methods.

    max_runs counts started runs. A firing is "pending" until run_started or run_skipped; when
    started plus pending runs reach max_runs, next_run becomes None. A skipped firing gives its
    slot back: next_run is computed again from the time the schedule was held. Pending counts
    are not saved: a node that dies between a firing and its start loses that slot.
    """

    def __init__(self) -> None:
        self._specs: dict[str, ScheduleSpec] = {}  # in creation order
        self._states: dict[str, ScheduleState] = {}
        self._heap: list[tuple[float, int, str]] = []
        self._queued: dict[str, tuple[float, int]] = {}  # id: its one valid heap entry
        self._sequence = 0
        self._pending: dict[str, int] = {}  # id: firings issued, not yet started nor skipped
        self._held: dict[str, float] = {}  # id: when max_runs stopped it with firings pending

    # ---- schedules -----------------------------------------------------------------------

    def add(self, spec: ScheduleSpec, state: ScheduleState | None = None) -> ScheduleState:
        """Add a schedule (a new one, or a stored one with its state); ValueError if its id is
        taken. Returns (a copy of) its state."""
        if spec.schedule_id in self._specs:
            raise ValueError(f"schedule '{spec.schedule_id}' exists")
        if state is None:
            state = ScheduleState(next_run=first_fire_time(spec))
        self._specs[spec.schedule_id] = spec
        self._states[spec.schedule_id] = dataclasses.replace(state)
        self._queue(spec.schedule_id)
        return dataclasses.replace(state)

    def remove(self, schedule_id: str) -> bool:
        if schedule_id not in self._specs:
            return False
        del self._specs[schedule_id], self._states[schedule_id]
        for table in (self._queued, self._pending, self._held):
            table.pop(schedule_id, None)
        return True

    def get(self, schedule_id: str) -> tuple[ScheduleSpec, ScheduleState] | None:
        if schedule_id not in self._specs:
            return None
        return self._specs[schedule_id], dataclasses.replace(self._states[schedule_id])

    def __len__(self) -> int:
        return len(self._specs)

    def __contains__(self, schedule_id: object) -> bool:
        return schedule_id in self._specs

    def ids(self) -> list[str]:
        """Every schedule id, in creation order."""
        return list(self._specs)

    def items(self) -> Iterator[tuple[ScheduleSpec, ScheduleState]]:
        """Every schedule and (a copy of) its state, in creation order."""
        for schedule_id, spec in self._specs.items():
            yield spec, dataclasses.replace(self._states[schedule_id])

    def set_enabled(self, schedule_id: str, enabled: bool, now: float) -> bool:
        """Enable or disable a schedule; returns whether that changed anything.

        Disabling keeps the state. Enabling computes next_run as the next fire time after
        `now`: times that fell due while disabled are neither run nor counted as missed, and
        a one-shot whose time passed meanwhile is finished (next_run None).
        """
        state = self._states.get(schedule_id)
        if state is None or state.enabled == enabled:
            return False
        state.enabled = enabled
        if enabled:
            state.next_run = self._next_run(schedule_id, now)
        self._queue(schedule_id)
        return True

    # ---- due times -----------------------------------------------------------------------

    def next_due(self) -> float | None:
        """The earliest next_run among enabled schedules (None when none will run)."""
        while self._heap and not self._is_current(self._heap[0]):
            heapq.heappop(self._heap)
        return self._heap[0][0] if self._heap else None

    def take_due(self, now: float) -> tuple[list[Firing], list[str]]:
        """The firings of every enabled schedule due at `now`, in due order, and the ids of
        the schedules whose state changed (to be saved).

        A schedule whose due times piled up (downtime, a busy node) fires once, for the
        latest of them, if that is within its misfire grace; the others count as missed.
        """
        firings: list[Firing] = []
        changed: list[str] = []
        while self._heap and self._heap[0][0] <= now:
            entry = heapq.heappop(self._heap)
            if not self._is_current(entry):
                continue
            schedule_id = entry[2]
            del self._queued[schedule_id]
            firing = self._fire(schedule_id, now)
            if firing is not None:
                firings.append(firing)
            changed.append(schedule_id)
            self._queue(schedule_id)
        return firings, changed

    def _fire(self, schedule_id: str, now: float) -> Firing | None:
        spec, state = self._specs[schedule_id], self._states[schedule_id]
        assert state.next_run is not None
        latest, count = latest_fire_at_or_before(spec, state.next_run, now)
        firing = None
        if now - latest <= spec.misfire_grace_sec:
            firing = Firing(schedule_id, latest, count - 1)
            state.missed_count += count - 1
            self._pending[schedule_id] = self._pending.get(schedule_id, 0) + 1
        else:
            state.missed_count += count
        state.next_run = self._next_run(schedule_id, now)
        return firing

    def _next_run(self, schedule_id: str, after: float) -> float | None:
        """The next fire time after `after`, or None once max_runs runs are started or pending."""
        spec, state = self._specs[schedule_id], self._states[schedule_id]
        if spec.max_runs and state.run_count + self._pending.get(schedule_id, 0) >= spec.max_runs:
            self._held[schedule_id] = after
            return None
        self._held.pop(schedule_id, None)
        return next_fire_after(spec, after)

    def _queue(self, schedule_id: str) -> None:
        """Make the heap hold the schedule's next_run (or nothing, when it will not run)."""
        state = self._states[schedule_id]
        if not state.enabled or state.next_run is None:
            self._queued.pop(schedule_id, None)
        else:
            self._sequence += 1
            self._queued[schedule_id] = (state.next_run, self._sequence)
            heapq.heappush(self._heap, (state.next_run, self._sequence, schedule_id))
        # stale entries only cost memory: rebuild when they outnumber the live ones
        if len(self._heap) > 2 * len(self._queued) + 64:
            self._heap = [(t, seq, key) for key, (t, seq) in self._queued.items()]
            heapq.heapify(self._heap)

    def _is_current(self, entry: tuple[float, int, str]) -> bool:
        return self._queued.get(entry[2]) == (entry[0], entry[1])

    # ---- runs ----------------------------------------------------------------------------

    def run_started(self, schedule_id: str, task_id: str, now: float) -> bool:
        """A firing's run started as `task_id`; False if the schedule is gone."""
        state = self._states.get(schedule_id)
        if state is None:
            return False
        self._release(schedule_id)
        state.run_count += 1
        state.last_run = now
        state.last_task_id = task_id
        state.last_status = 'IN_PROGRESS'
        return True

    def run_skipped(self, schedule_id: str) -> bool:
        """A firing was skipped by the overlap policy; gives its max_runs slot back."""
        state = self._states.get(schedule_id)
        if state is None:
            return False
        self._release(schedule_id)
        state.skipped_count += 1
        held = self._held.get(schedule_id)
        if state.next_run is None and held is not None:
            state.next_run = self._next_run(schedule_id, held)
            self._queue(schedule_id)
        return True

    def run_ended(self, schedule_id: str, task_id: str, status: str) -> bool:
        """A run ended; records its status if it is the schedule's last run."""
        state = self._states.get(schedule_id)
        if state is None or task_id != state.last_task_id:
            return False
        state.last_status = status
        return True

    def _release(self, schedule_id: str) -> None:
        pending = self._pending.get(schedule_id, 0)
        if pending > 1:
            self._pending[schedule_id] = pending - 1
        else:
            self._pending.pop(schedule_id, None)
