"""Who may run: the resources held, the queue, and each request's verdict with its reason.

Rules (docs/deciding-what-runs.md):
- A request whose resources are free, and wanted by no queued task of at least its priority,
  starts at once.
- Otherwise its on_conflict says what happens. `preempt`: it cancels the holders if its
  priority is at least each one's (refused `preemption_refused` if not, or if a queued task of
  at least its priority waits for the same resources). `queue`: it waits (refused `queue_full`
  beyond max_queued). `reject`: refused `resource_busy`.
- The queue is served by priority, then arrival: a queued task starts once its resources are
  free and no task ahead of it in the queue still waits for one of them.
- A subtask may use what its missions hold: a mission claims its subtasks' resources as a unit.
  A task queued for what a mission holds does not hold back the mission's subtasks.
- A pre-empted task is still ending until it is released: whoever starts on one of its
  resources waits for it (`still_ending`); if its pre-emptor gives up before it has cancelled
  it, it holds its resources again (`reinstate`).
"""

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from types import MappingProxyType

from task_manager.core.admission.claims import Claim, resource_words
from task_manager.core.admission.options import OnConflict
from task_manager.core.status import ErrorCode

DEFAULT_MAX_QUEUED = 100


class Verdict(StrEnum):
    START = 'start'
    QUEUE = 'queue'
    REFUSE = 'refuse'


@dataclass(frozen=True)
class Preemption:
    """A holder the new task cancels, and the words its own record keeps."""

    victim: Claim
    reason: str


@dataclass(frozen=True)
class Decision:
    """The verdict on one request, and why (empty when it simply starts)."""

    verdict: Verdict
    reason: str = ''
    error_code: ErrorCode = ErrorCode.NONE
    preemptions: tuple[Preemption, ...] = field(default=())
    position: int = 0
    """QUEUE: its place in the queue, 1 first."""


class Arbiter:
    """The resources held by running tasks and the tasks queued for theirs."""

    def __init__(self, max_queued: int = DEFAULT_MAX_QUEUED) -> None:
        self.max_queued = max_queued
        # key: task id, value: the claim of a task that holds its resources (started or starting)
        self._holders: dict[str, Claim] = {}
        # key: a resource, value: the ids of its holders, each with the order it took it in;
        # a thousand reentrant tasks that hold nothing cost a new request nothing
        self._holders_of: dict[str, dict[str, int]] = {}
        self._holds = 0
        # key: task id, value: the claim of a holder pre-empted but not yet ended
        self.displaced: dict[str, Claim] = {}
        # key: the id of a displaced task, value: the id of the task that pre-empted it
        self._preempted_by: dict[str, str] = {}
        # the queued claims, in the order they are served
        self._queue: list[Claim] = []
        self._arrivals = 0

    # ---- questions ----------------------------------------------------------------------------

    @property
    def holders(self) -> Mapping[str, Claim]:
        """key: task id, value: the claim of a task that holds its resources (started or
        starting), in the order they took them."""
        return MappingProxyType(self._holders)

    @property
    def queued(self) -> list[Claim]:
        """Queued claims, first served first."""
        return list(self._queue)

    def position(self, task_id: str) -> int:
        """1 for the first queued task; 0 when it is not queued."""
        for index, claim in enumerate(self._queue):
            if claim.task_id == task_id:
                return index + 1
        return 0

    def is_queued(self, task_id: str) -> bool:
        return any(claim.task_id == task_id for claim in self._queue)

    def blockers(self, claim: Claim) -> list[tuple[Claim, frozenset[str]]]:
        """Holders that share a resource with `claim`, and what they share."""
        held_since: dict[str, int] = {}
        for resource in claim.resources:
            held_since.update(self._holders_of.get(resource, {}))
        if not held_since:
            return []
        related = self._lineage(claim)
        found = []
        for task_id in sorted(held_since, key=held_since.__getitem__):
            holder = self._holders[task_id]
            if task_id not in related:
                found.append((holder, holder.resources & claim.resources))
        return found

    def still_ending(self, claim: Claim) -> list[Claim]:
        """Pre-empted tasks that have not ended yet and share a resource with `claim`: it
        starts only once they have (a task pre-empted by a task that was itself pre-empted
        before it could start is waited for by the newest)."""
        related = self._lineage(claim)
        return [
            ending
            for ending in self.displaced.values()
            if ending.resources & claim.resources and ending.task_id not in related
        ]

    def reinstate(self, task_id: str) -> bool:
        """A pre-empted task goes on after all (its pre-emptor ended first): it holds its
        resources again, if no holder has taken one of them meanwhile.

        Its pre-emptor may still hold them (it is released after): it is giving them back.
        """
        claim = self.displaced.get(task_id)
        if claim is None:
            return False
        preemptor = self._preempted_by.get(task_id)
        if any(holder.task_id != preemptor for holder, _ in self.blockers(claim)):
            return False
        self._hold(self.displaced.pop(task_id))
        self._preempted_by.pop(task_id, None)
        return True

    # ---- decisions ----------------------------------------------------------------------------

    def decide(self, claim: Claim, on_conflict: OnConflict) -> Decision:
        """The verdict on a new request; START and QUEUE take effect here."""
        self._arrivals += 1
        claim.arrival = self._arrivals
        holders = self.blockers(claim)
        ahead = self._queued_ahead(claim)
        if not holders and not ahead:
            self._hold(claim)
            return Decision(Verdict.START)
        if on_conflict is OnConflict.QUEUE:
            return self._enqueue(claim, holders, ahead)
        if on_conflict is OnConflict.REJECT:
            return Decision(
                Verdict.REFUSE,
                'refused: ' + _busy_words(holders, ahead),
                ErrorCode.RESOURCE_BUSY,
            )
        return self._preempt(claim, holders, ahead)

    def release(self, task_id: str) -> list[Claim]:
        """A task ended (or left the queue): the queued tasks that start now, in order."""
        self._release_hold(task_id)
        self.displaced.pop(task_id, None)
        self._preempted_by.pop(task_id, None)
        self._queue = [claim for claim in self._queue if claim.task_id != task_id]
        return self._serve_queue()

    def reprioritize(self, task_id: str, priority: int) -> list[Claim] | None:
        """Change an active task's priority; None when it holds nothing and is not queued.

        A queued task moves in the queue; the queued tasks that may start now are returned.
        """
        claim = self._holders.get(task_id) or next(
            (queued for queued in self._queue if queued.task_id == task_id), None
        )
        if claim is None:
            return None
        claim.priority = priority
        self._queue.sort(key=_queue_order)
        return self._serve_queue()

    # ---- inside -----------------------------------------------------------------------------

    def _hold(self, claim: Claim) -> None:
        self._holds += 1
        self._holders[claim.task_id] = claim
        for resource in claim.resources:
            self._holders_of.setdefault(resource, {})[claim.task_id] = self._holds

    def _release_hold(self, task_id: str) -> None:
        claim = self._holders.pop(task_id, None)
        if claim is None:
            return
        for resource in claim.resources:
            holders = self._holders_of[resource]
            del holders[task_id]
            if not holders:
                del self._holders_of[resource]

    def _lineage(self, claim: Claim) -> set[str]:
        """The ids of the missions `claim` runs in (their holds are its own)."""
        lineage: set[str] = set()
        parent_id = claim.parent_id
        while parent_id and parent_id not in lineage:
            lineage.add(parent_id)
            parent = self._holders.get(parent_id)
            parent_id = parent.parent_id if parent is not None else ''
        return lineage

    def _queued_ahead(self, claim: Claim) -> list[tuple[Claim, frozenset[str]]]:
        """Queued tasks of at least `claim`'s priority that wait for one of its resources."""
        found = []
        for queued in self._queue:
            if queued.priority >= claim.priority:
                shared = self._contended(queued, claim)
                if shared:
                    found.append((queued, shared))
        return found

    def _contended(self, ahead: Claim, claim: Claim) -> frozenset[str]:
        """What `claim` wants that `ahead`, queued before it, waits for too.

        What a mission of `claim` holds is not `ahead`'s to wait for (unless it runs in that
        mission too): it comes free only once the mission, and so `claim`, has ended.
        """
        shared = ahead.resources & claim.resources
        if not shared or not claim.parent_id:
            return shared
        for mission_id in self._lineage(claim) - self._lineage(ahead):
            mission = self._holders.get(mission_id)
            if mission is not None:
                shared -= mission.resources
        return shared

    def _enqueue(
        self,
        claim: Claim,
        holders: list[tuple[Claim, frozenset[str]]],
        ahead: list[tuple[Claim, frozenset[str]]],
    ) -> Decision:
        if len(self._queue) >= self.max_queued:
            return Decision(
                Verdict.REFUSE,
                f'refused: {_busy_words(holders, ahead)}, and the queue is full '
                f'(max_queued {self.max_queued})',
                ErrorCode.QUEUE_FULL,
            )
        self._queue.append(claim)
        self._queue.sort(key=_queue_order)
        position = self.position(claim.task_id)
        return Decision(
            Verdict.QUEUE, f'queued behind {_busy_words(holders, ahead)}', position=position
        )

    def _preempt(
        self,
        claim: Claim,
        holders: list[tuple[Claim, frozenset[str]]],
        ahead: list[tuple[Claim, frozenset[str]]],
    ) -> Decision:
        stronger = [(h, shared) for h, shared in holders if h.priority > claim.priority]
        if stronger:
            holder, shared = max(stronger, key=lambda item: item[0].priority)
            return Decision(
                Verdict.REFUSE,
                f"refused: priority {claim.priority} is below {holder.task_id}'s "
                f'{holder.priority}, which holds {resource_words(shared)}',
                ErrorCode.PREEMPTION_REFUSED,
            )
        if ahead:
            queued, shared = ahead[0]
            return Decision(
                Verdict.REFUSE,
                f'refused: {queued.label()} is queued first for {resource_words(shared)}',
                ErrorCode.PREEMPTION_REFUSED,
            )
        preemptions = tuple(
            Preemption(
                holder,
                f'cancelled: pre-empted by {claim.label()} for {resource_words(shared)}',
            )
            for holder, shared in holders
        )
        for holder, _ in holders:
            self.displaced[holder.task_id] = holder
            self._release_hold(holder.task_id)
            self._preempted_by[holder.task_id] = claim.task_id
        self._hold(claim)
        victims = ', '.join(p.victim.label() for p in preemptions)
        return Decision(Verdict.START, f'pre-empts {victims}', preemptions=preemptions)

    def _serve_queue(self) -> list[Claim]:
        started: list[Claim] = []
        waiting: list[Claim] = []
        wanted: set[str] = set()
        for claim in list(self._queue):
            held_back = bool(claim.resources & wanted)
            if held_back and claim.parent_id:
                held_back = any(self._contended(ahead, claim) for ahead in waiting)
            if not held_back and not self.blockers(claim):
                self._queue.remove(claim)
                self._hold(claim)
                started.append(claim)
            else:
                waiting.append(claim)
                wanted |= claim.resources
        return started


def _queue_order(claim: Claim) -> tuple[int, int]:
    return (-claim.priority, claim.arrival)


def _busy_words(
    holders: Iterable[tuple[Claim, frozenset[str]]], ahead: Iterable[tuple[Claim, frozenset[str]]]
) -> str:
    """`navigate-12 (priority 5), which holds base; dock-3 (priority 5), queued for base`."""
    parts = [f'{h.label()}, which holds {resource_words(shared)}' for h, shared in holders]
    parts += [f'{q.label()}, queued for {resource_words(shared)}' for q, shared in ahead]
    return '; '.join(parts)
