"""Starting the runs of every schedule from one timer, set for the next due one.

Each run is an ordinary task request through the dispatcher (conflicts, results, events,
history), with id `<schedule_id>-run-<n>` and source `schedule:<schedule_id>`. The schedules
and their states are stored in the history file; a change is saved in one transaction per
executor turn. Nothing here polls: the one timer rings at the next due time (set a little
short of it, then again for the rest: core.schedules.timer_delay), or after MAX_TIMER_SEC at
the latest, so that a wall clock that jumps forward is noticed soon.
"""

import sqlite3
import time
from collections.abc import Iterable
from typing import Protocol

from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.node import Node

from task_manager.core.admission.options import RequestOptions
from task_manager.core.bounds import cut_text
from task_manager.core.schedules.book import (
    Firing,
    RunAction,
    ScheduleBook,
    ScheduleState,
    overlap_action,
    run_source,
    run_task_id,
)
from task_manager.core.schedules.schedule import ScheduleSpec
from task_manager.core.schedules.store import ScheduleStore
from task_manager.core.schedules.timer_delay import MAX_TIMER_SEC, timer_delay
from task_manager.core.status import CancelReason
from task_manager.core.task import TaskRequest
from task_manager.rclpy_tools.futures import all_completed, resolved
from task_manager.rclpy_tools.log import NodeLog
from task_manager.ros.parking_executor import spawn
from task_manager.ros.running.protocols import TaskCancelling, TaskRunning


class ScheduledTasks(TaskRunning, TaskCancelling, Protocol):
    """What the runs of schedules need: a run is a request, and CANCEL_OTHER cancels runs."""


class TaskScheduler:
    """The node's schedules: add, remove, enable, read, and start their runs when due."""

    def __init__(self, node: Node, tasks: ScheduledTasks, store: ScheduleStore) -> None:
        self.book = ScheduleBook()
        self._node = node
        self._tasks = tasks
        self._store = store
        self._log = NodeLog.of(node, 'schedules')
        # key: schedule id, value: the task ids of its runs that have not ended
        self._active_runs: dict[str, set[str]] = {}
        # ids of BUFFER_ONE schedules with a run waiting for the previous one to end
        self._buffered: set[str] = set()
        self._dirty: set[str] = set()
        self._save_pending = False
        self._stopped = False
        self._timer = node.create_timer(
            MAX_TIMER_SEC, self._on_timer, clock=Clock(clock_type=ClockType.STEADY_TIME)
        )
        self._timer.cancel()

    def start(self) -> None:
        """Load the stored schedules and set the timer; runs missed meanwhile are due now."""
        stored, unreadable = self._store.load()
        for spec, state in stored:
            self.book.add(spec, state)
        for schedule_id, why in unreadable:
            self._log.error(
                f'schedule {cut_text(schedule_id)!r} in the history file cannot be run by this '
                f'version ({cut_text(why)}); it is left as it is and does not run'
            )
        if stored:
            self._log.info(f'{len(stored)} schedule(s) loaded')
        self._arm()

    def stop(self) -> None:
        """Start no more runs (the node is shutting down)."""
        self._stopped = True
        self._timer.cancel()

    # ---- changes ----------------------------------------------------------------------------

    def add(self, spec: ScheduleSpec) -> ScheduleState:
        """Store and arm a new schedule; ValueError if its id is taken."""
        state = self.book.add(spec)
        self._store.save(spec, state)
        self._log.info(
            f'schedule {spec.schedule_id!r} added by {spec.created_by!r}: {spec.task_name}, '
            f'{spec.describe()}'
        )
        self._arm()
        return state

    def remove(self, schedule_ids: Iterable[str]) -> list[str]:
        """Remove schedules (their runs already started go on); returns the ids removed."""
        removed = [s for s in schedule_ids if self.book.remove(s)]
        self._store.delete(removed)
        for schedule_id in removed:
            self._buffered.discard(schedule_id)
            self._dirty.discard(schedule_id)
        if removed:
            self._log.info('schedule(s) removed: ' + ', '.join(removed))
            self._arm()
        return removed

    def set_enabled(self, schedule_ids: Iterable[str], enabled: bool) -> list[str]:
        """Enable or disable schedules; returns the ids that are schedules."""
        known = [s for s in schedule_ids if s in self.book]
        now = time.time()
        changed = [s for s in known if self.book.set_enabled(s, enabled, now)]
        if changed:
            self._log.info(
                f'schedule(s) {"enabled" if enabled else "disabled"}: ' + ', '.join(changed)
            )
            self._save(changed)
            self._arm()
        return known

    # ---- firing -----------------------------------------------------------------------------

    def _arm(self) -> None:
        """Set the one timer for the next due schedule (or for MAX_TIMER_SEC)."""
        self._timer.cancel()
        due = self.book.next_due()
        if due is None or self._stopped:
            return
        self._timer.timer_period_ns = round(timer_delay(due - time.time()) * 1e9)
        self._timer.reset()

    def _on_timer(self) -> None:
        self._timer.cancel()
        now = time.time()
        firings, changed = self.book.take_due(now)
        for firing in firings:
            self._fire(firing, now)
        self._missed(changed, firings)
        self._save(changed)
        self._arm()

    def _missed(self, changed: list[str], firings: list[Firing]) -> None:
        fired = {firing.schedule_id: firing for firing in firings}
        for schedule_id in changed:
            firing = fired.get(schedule_id)
            if firing is not None and firing.coalesced:
                self._log.warning(
                    f'schedule {schedule_id!r}: {firing.coalesced} earlier due run(s) missed; '
                    'they are coalesced into this one'
                )
            elif firing is None:
                self._log.warning(
                    f'schedule {schedule_id!r}: a due run was later than its misfire_grace '
                    '(the Task Manager was down, or the clock jumped); recorded as missed'
                )

    def _fire(self, firing: Firing, now: float) -> None:
        schedule_id = firing.schedule_id
        found = self.book.get(schedule_id)
        assert found is not None, 'a schedule that fires is in the book'
        spec = found[0]
        active = self._active_runs.get(schedule_id, set())
        action = overlap_action(spec.overlap, bool(active), schedule_id in self._buffered)
        if action is RunAction.START:
            self._start_run(schedule_id, now)
        elif action is RunAction.BUFFER:
            self._buffered.add(schedule_id)
        elif action is RunAction.CANCEL_AND_START:
            spawn(self._node, self._replace_runs(schedule_id, list(active)))
        else:
            self.book.run_skipped(schedule_id)
            self._log.info(
                f'schedule {schedule_id!r}: run skipped, the previous one '
                f'({", ".join(sorted(active))}) is still active (overlap {spec.overlap})'
            )

    async def _replace_runs(self, schedule_id: str, task_ids: list[str]) -> None:
        """CANCEL_OTHER: cancel the runs still active, then start the new one."""
        cancels = [self._tasks.cancel(t, CancelReason.SCHEDULE) for t in task_ids]
        await resolved(self._node, all_completed(cancels))
        if schedule_id in self.book and not self._stopped:
            self._start_run(schedule_id, time.time())
            self._save([schedule_id])

    def _start_run(self, schedule_id: str, now: float) -> None:
        found = self.book.get(schedule_id)
        assert found is not None
        spec, state = found
        task_id = run_task_id(schedule_id, state.run_count + 1)
        self.book.run_started(schedule_id, task_id, now)
        self._active_runs.setdefault(schedule_id, set()).add(task_id)
        request = TaskRequest(
            task_id,
            spec.task_name,
            run_source(schedule_id),
            spec.task_data,
            options=RequestOptions.from_dict(spec.options),
        )
        spawn(self._node, self._run(schedule_id, request))

    async def _run(self, schedule_id: str, request: TaskRequest) -> None:
        record = await self._tasks.run(request)
        active = self._active_runs.get(schedule_id, set())
        active.discard(record.task_id)
        if not active:
            self._active_runs.pop(schedule_id, None)
        if self.book.run_ended(schedule_id, record.task_id, str(record.status)):
            self._save([schedule_id])
        if schedule_id in self._buffered and not active and not self._stopped:
            self._buffered.discard(schedule_id)
            if schedule_id in self.book:
                self._start_run(schedule_id, time.time())
                self._save([schedule_id])

    # ---- saving -----------------------------------------------------------------------------

    def _save(self, schedule_ids: Iterable[str]) -> None:
        """Save these states with the other changes of this executor turn (one transaction)."""
        self._dirty.update(schedule_ids)
        if self._dirty and not self._save_pending:
            self._save_pending = True
            spawn(self._node, self._flush())

    async def _flush(self) -> None:
        self._save_pending = False
        dirty, self._dirty = self._dirty, set()
        states = []
        for schedule_id in dirty:
            found = self.book.get(schedule_id)
            if found is not None:
                states.append((schedule_id, found[1]))
        try:
            self._store.save_states(states)
        except sqlite3.Error as error:
            self._log.error(f'cannot save {len(states)} schedule state(s): {error}')
