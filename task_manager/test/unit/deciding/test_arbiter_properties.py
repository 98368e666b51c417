"""Property tests of the arbiter: random arrivals, ends, withdrawals and priority changes keep
its rules (examples of each rule: test_arbiter.py)."""

import itertools
from dataclasses import dataclass, field
from enum import Enum

from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, precondition, rule

from task_manager.core.admission.arbiter import Arbiter, Verdict
from task_manager.core.admission.claims import Claim, implied_resources
from task_manager.core.admission.options import OnConflict
from task_manager.core.status import ErrorCode


def ids(claims: list[Claim]) -> list[str]:
    return [c.task_id for c in claims]


# ---- property: random arrivals, ends, withdrawals and priority changes -------------------------


class State(Enum):
    RUNNING = 'running'
    QUEUED = 'queued'
    REFUSED = 'refused'
    PREEMPTED = 'preempted'
    RELEASED = 'released'


ACTIVE = (State.RUNNING, State.QUEUED)


@dataclass
class Request:
    """The model's own copy of one request (the arbiter changes its claims in place)."""

    task_id: str
    resources: frozenset[str]
    priority: int
    parent_id: str
    arrival: int
    state: State = State.RUNNING
    ends: list[State] = field(default_factory=list)


resource_names = st.sampled_from(['base', 'arm', 'camera'])
resource_sets = st.one_of(
    st.frozensets(resource_names, min_size=1, max_size=2),
    st.builds(
        implied_resources,
        task_name=st.sampled_from(['nav', 'dock']),
        declared=st.frozensets(resource_names, max_size=2),
        blocking=st.booleans(),
        reentrant=st.booleans(),
    ),
)


class Arbitration(RuleBasedStateMachine):
    """Requests arrive, run, wait, end, leave the queue and change priority in any order.

    The model follows the arbiter's answers only: START holds its resources, a pre-emption
    ends its victims (which the node releases once their cancel is done: until then they are
    still ending, and whoever starts on one of their resources waits for them), a release's
    starters hold theirs. A subtask is a child of a running task; a
    task that ends takes its subtasks with it (a mission cancels its subtasks), and no task
    outlives its mission.
    """

    def __init__(self) -> None:
        super().__init__()
        self.arbiter = Arbiter()
        self.requests: dict[str, Request] = {}
        self.stopping: list[str] = []
        # key: a pre-empted task's id, value: the id of the task that pre-empted it
        self.preempted_by: dict[str, str] = {}
        self.numbers = itertools.count(1)

    @initialize(max_queued=st.integers(1, 5))
    def bound_the_queue(self, max_queued: int) -> None:
        self.arbiter = Arbiter(max_queued)

    # ---- the model's questions --------------------------------------------------------------

    def in_state(self, state: State) -> list[Request]:
        return [r for r in self.requests.values() if r.state is state]

    def queue(self) -> list[Request]:
        return sorted(self.in_state(State.QUEUED), key=lambda r: (-r.priority, r.arrival))

    def ancestors(self, request: Request) -> set[str]:
        found: set[str] = set()
        parent_id = request.parent_id
        while parent_id:
            found.add(parent_id)
            parent_id = self.requests[parent_id].parent_id
        return found

    def still_ending(self, request: Request) -> list[Request]:
        """Pre-empted tasks not yet released that share a resource with `request`."""
        return [
            victim
            for victim in map(self.requests.__getitem__, self.stopping)
            if victim.resources & request.resources
        ]

    def busy_for(self, request: Request) -> frozenset[str]:
        """What others hold of `request`'s resources: running (not its missions) or ending."""
        lineage = self.ancestors(request) | {request.task_id}
        held: set[str] = set()
        for other in self.in_state(State.RUNNING):
            if other.task_id not in lineage:
                held |= other.resources & request.resources
        for victim in self.still_ending(request):
            held |= victim.resources & request.resources
        return frozenset(held)

    def contended(self, first: Request, then: Request) -> frozenset[str]:
        """What `then` wants that `first`, ahead of it, waits for too.

        A resource held by a mission of `then` that is not `first`'s mission is not `first`'s
        to wait for: it comes free only after `then` and its mission have ended.
        """
        shared = set(first.resources & then.resources)
        for ancestor_id in self.ancestors(then) - self.ancestors(first):
            shared -= self.requests[ancestor_id].resources
        return frozenset(shared)

    # ---- carrying out the arbiter's answers --------------------------------------------------

    def end(self, request: Request, state: State) -> None:
        assert request.state in ACTIVE, f'{request.task_id} ends twice'
        request.state = state
        request.ends.append(state)

    def start(self, started: list[Claim]) -> None:
        """Queued tasks start, in queue order, none past one still waiting for its resources."""
        queue = self.queue()
        assert ids(started) == [r.task_id for r in queue if r.task_id in ids(started)]
        for claim_ in started:
            request = self.requests[claim_.task_id]
            assert request.state is State.QUEUED, f'{request.task_id} starts, not queued'
            request.state = State.RUNNING
        for index, request in enumerate(queue):
            if request.state is State.RUNNING:
                jumped = [a.task_id for a in queue[:index] if a.state is State.QUEUED]
                assert not any(self.contended(self.requests[a], request) for a in jumped), (
                    f'{request.task_id} starts past {jumped}'
                )

    def end_subtasks(self, mission: Request) -> None:
        """A mission that ends cancels its subtasks, the queued ones first."""
        while subtasks := [
            r
            for r in self.requests.values()
            if r.state in ACTIVE and mission.task_id in self.ancestors(r)
        ]:
            self.release(max(subtasks, key=lambda r: r.state is State.QUEUED))

    def release(self, request: Request) -> None:
        """`request` ends or leaves the queue, after its subtasks (the node's release)."""
        self.end_subtasks(request)
        self.end(request, State.RELEASED)
        self.start(self.arbiter.release(request.task_id))

    # ---- rules ------------------------------------------------------------------------------

    @rule(
        resources=resource_sets,
        priority=st.integers(0, 3),
        on_conflict=st.sampled_from(OnConflict),
        parent=st.none() | st.integers(0, 50),
    )
    def arrive(
        self,
        resources: frozenset[str],
        priority: int,
        on_conflict: OnConflict,
        parent: int | None,
    ) -> None:
        self.decide(resources, priority, on_conflict, parent)

    @rule(resources=resource_sets, priority=st.integers(0, 3))
    def arrive_to_wait(self, resources: frozenset[str], priority: int) -> None:
        """Arrivals that queue make the queue's orders (a second rule: they come more often)."""
        self.decide(resources, priority, OnConflict.QUEUE, None)

    def decide(
        self,
        resources: frozenset[str],
        priority: int,
        on_conflict: OnConflict,
        parent: int | None,
    ) -> None:
        running = self.in_state(State.RUNNING)
        parent_id = running[parent % len(running)].task_id if running and parent is not None else ''
        number = next(self.numbers)
        request = Request(f't{number}', resources, priority, parent_id, number)
        self.requests[request.task_id] = request
        holders = [
            r
            for r in running
            if r.task_id not in self.ancestors(request) and r.resources & resources
        ]
        ahead = [q for q in self.queue() if q.priority >= priority and self.contended(q, request)]
        queue_length = len(self.queue())

        decision = self.arbiter.decide(
            Claim(request.task_id, 'task', resources, priority, parent_id), on_conflict
        )

        if decision.verdict is Verdict.START and not decision.preemptions:
            assert not holders and not ahead
            assert decision.reason == ''
            return
        assert holders or ahead, f'{decision} with nothing in the way'
        if decision.verdict is Verdict.START:
            assert on_conflict is OnConflict.PREEMPT and not ahead
            victims = [self.requests[p.victim.task_id] for p in decision.preemptions]
            assert sorted(v.task_id for v in victims) == sorted(h.task_id for h in holders)
            for victim, preemption in zip(victims, decision.preemptions, strict=True):
                assert victim.priority <= priority, 'a lower priority pre-empted a higher'
                assert preemption.reason.startswith(
                    f'cancelled: pre-empted by {request.task_id} (priority {priority}) for '
                )
                self.end(victim, State.PREEMPTED)
                self.stopping.append(victim.task_id)
                self.preempted_by[victim.task_id] = request.task_id
            for victim in victims:
                self.end_subtasks(victim)
            return
        if decision.verdict is Verdict.QUEUE:
            assert on_conflict is OnConflict.QUEUE and queue_length < self.arbiter.max_queued
            assert decision.reason.startswith('queued behind ')
            request.state = State.QUEUED
            assert decision.position == [r.task_id for r in self.queue()].index(request.task_id) + 1
            return
        assert decision.verdict is Verdict.REFUSE and decision.reason.startswith('refused: ')
        if on_conflict is OnConflict.QUEUE:
            assert decision.error_code is ErrorCode.QUEUE_FULL
            assert queue_length >= self.arbiter.max_queued
        elif on_conflict is OnConflict.REJECT:
            assert decision.error_code is ErrorCode.RESOURCE_BUSY
        else:
            assert decision.error_code is ErrorCode.PREEMPTION_REFUSED
            assert ahead or any(h.priority > priority for h in holders)
        self.end(request, State.REFUSED)

    @precondition(lambda self: self.in_state(State.RUNNING))
    @rule(index=st.integers(0, 50))
    def a_running_task_ends(self, index: int) -> None:
        running = self.in_state(State.RUNNING)
        self.release(running[index % len(running)])

    @precondition(lambda self: self.in_state(State.QUEUED))
    @rule(index=st.integers(0, 50))
    def a_queued_task_is_cancelled_or_times_out(self, index: int) -> None:
        queued = self.in_state(State.QUEUED)
        self.release(queued[index % len(queued)])

    @precondition(lambda self: self.stopping)
    @rule(index=st.integers(0, 50))
    def a_preempted_task_has_ended(self, index: int) -> None:
        task_id = self.stopping.pop(index % len(self.stopping))
        self.start(self.arbiter.release(task_id))

    def preemptors_yet_to_cancel(self) -> list[Request]:
        """Running tasks whose victims are still ending (their cancel may not have begun)."""
        ids_ = {self.preempted_by[v] for v in self.stopping if v in self.preempted_by}
        return [r for r in self.in_state(State.RUNNING) if r.task_id in ids_]

    @precondition(lambda self: self.preemptors_yet_to_cancel())
    @rule(index=st.integers(0, 50))
    def a_preemptor_gives_up_before_it_cancels(self, index: int) -> None:
        """It ends before it has cancelled its victims: each one holds its resources again,
        unless another task took one of them meanwhile; then it stays pre-empted (the node
        cancels it): it never runs on holding nothing beside that task."""
        preemptors = self.preemptors_yet_to_cancel()
        preemptor = preemptors[index % len(preemptors)]
        victims = [v for v in self.stopping if self.preempted_by.get(v) == preemptor.task_id]
        for victim in map(self.requests.__getitem__, victims):
            if any(self.requests[a].state is not State.RUNNING for a in self.ancestors(victim)):
                continue  # its mission is ending: it cancels the victim
            lineage = self.ancestors(victim) | {preemptor.task_id}
            taken = [
                r
                for r in self.in_state(State.RUNNING)
                if r.task_id not in lineage and r.resources & victim.resources
            ]
            assert self.arbiter.reinstate(victim.task_id) is not bool(taken), (victim, taken)
            if not taken:
                self.stopping.remove(victim.task_id)
                victim.state = State.RUNNING
                victim.ends.pop()
        self.release(preemptor)

    @precondition(lambda self: self.in_state(State.QUEUED))
    @rule(index=st.integers(0, 50), priority=st.integers(0, 3))
    def a_queued_priority_changes(self, index: int, priority: int) -> None:
        queued = self.in_state(State.QUEUED)
        self.change_priority(queued[index % len(queued)], priority)

    @precondition(lambda self: self.in_state(State.RUNNING))
    @rule(index=st.integers(0, 50), priority=st.integers(0, 3))
    def a_running_priority_changes(self, index: int, priority: int) -> None:
        running = self.in_state(State.RUNNING)
        self.change_priority(running[index % len(running)], priority)

    def change_priority(self, request: Request, priority: int) -> None:
        started = self.arbiter.reprioritize(request.task_id, priority)
        assert started is not None
        request.priority = priority
        self.start(started)

    @precondition(lambda self: self.requests)
    @rule(index=st.integers(0, 50))
    def an_ended_task_is_released_again(self, index: int) -> None:
        ended = [
            r
            for r in self.requests.values()
            if r.state not in ACTIVE and r.task_id not in self.stopping
        ]
        if ended:
            task_id = ended[index % len(ended)].task_id
            assert self.arbiter.reprioritize(task_id, 3) is None
            started = self.arbiter.release(task_id)
            assert self.stopping or started == [], 'a release that frees nothing starts a task'
            self.start(started)

    # ---- invariants -------------------------------------------------------------------------

    @invariant()
    def the_arbiter_agrees_with_the_model(self) -> None:
        assert sorted(self.arbiter.holders) == sorted(
            r.task_id for r in self.in_state(State.RUNNING)
        )
        assert ids(self.arbiter.queued) == [r.task_id for r in self.queue()]

    @invariant()
    def whoever_holds_what_an_ending_task_held_waits_for_it(self) -> None:
        assert list(self.arbiter.displaced) == self.stopping
        for holder in self.in_state(State.RUNNING):
            claim_ = self.arbiter.holders[holder.task_id]
            assert ids(self.arbiter.still_ending(claim_)) == [
                victim.task_id for victim in self.still_ending(holder)
            ]

    @invariant()
    def position_agrees_with_the_queue(self) -> None:
        order = ids(self.arbiter.queued)
        for task_id in self.requests:
            expected = order.index(task_id) + 1 if task_id in order else 0
            assert self.arbiter.position(task_id) == expected
            assert self.arbiter.is_queued(task_id) is bool(expected)

    @invariant()
    def holders_that_are_not_one_mission_share_nothing(self) -> None:
        running = self.in_state(State.RUNNING)
        for first, second in itertools.combinations(running, 2):
            related = first.task_id in self.ancestors(second) or (
                second.task_id in self.ancestors(first)
            )
            assert related or not first.resources & second.resources, (first, second)

    @invariant()
    def nothing_waits_needlessly(self) -> None:
        queue = self.queue()
        for index, waiting in enumerate(queue):
            contenders = [a for a in queue[:index] if self.contended(a, waiting)]
            assert self.busy_for(waiting) or contenders, f'{waiting.task_id} waits for nothing'

    @invariant()
    def every_request_ends_at_most_once(self) -> None:
        for request in self.requests.values():
            assert len(request.ends) <= 1
            assert (request.state in ACTIVE) is (not request.ends)


Arbitration.TestCase.settings = settings(max_examples=120, stateful_step_count=30, deadline=None)
test_arbitration = Arbitration.TestCase
