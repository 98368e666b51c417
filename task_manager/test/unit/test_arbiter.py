"""Tests of the arbiter: who starts, who waits, who is refused or pre-empted, and why."""

import itertools
from dataclasses import dataclass, field
from enum import Enum

import pytest
from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, precondition, rule

from task_manager.core.admission.arbiter import Arbiter, Decision, Verdict
from task_manager.core.admission.claims import (
    BLOCKING,
    Claim,
    implied_resources,
    resource_words,
    task_slot,
)
from task_manager.core.admission.options import OnConflict
from task_manager.core.status import ErrorCode

NAVIGATE = 'navigation/navigate_to_pose'
DOCK = 'navigation/dock'
PHOTO = 'camera/take_photo'


def claim(
    task_id: str, *resources: str, priority: int = 0, parent_id: str = '', name: str = ''
) -> Claim:
    return Claim(task_id, name or task_id, frozenset(resources), priority, parent_id)


def declared(
    task_id: str, task_name: str, *, blocking: bool = False, reentrant: bool = False
) -> Claim:
    """A claim as the original's declarations make it: no resources listed."""
    return Claim(task_id, task_name, implied_resources(task_name, (), blocking, reentrant))


def arbiter_with(*holders: Claim, max_queued: int = 100) -> Arbiter:
    arbiter = Arbiter(max_queued)
    for holder in holders:
        assert arbiter.decide(holder, OnConflict.PREEMPT) == Decision(Verdict.START)
    return arbiter


def ids(claims: list[Claim]) -> list[str]:
    return [c.task_id for c in claims]


# ---- starting, queueing, refusing, pre-empting: the words ------------------------------


def test_a_task_whose_resources_are_free_starts_at_once_and_holds_them() -> None:
    arbiter = arbiter_with(claim('navigate-12', 'base', priority=5))
    decision = arbiter.decide(claim('photo-1', 'camera'), OnConflict.PREEMPT)
    assert decision == Decision(Verdict.START)
    assert sorted(arbiter.holders) == ['navigate-12', 'photo-1']
    assert arbiter.queued == []


def test_queue_waits_behind_the_holder_and_says_who_holds_what() -> None:
    arbiter = arbiter_with(claim('navigate-12', 'base', priority=5))
    decision = arbiter.decide(claim('dock-3', 'base', priority=7), OnConflict.QUEUE)
    assert decision.verdict is Verdict.QUEUE
    assert decision.reason == 'queued behind navigate-12 (priority 5), which holds base'
    assert decision.error_code is ErrorCode.NONE
    assert decision.position == 1
    assert arbiter.is_queued('dock-3')
    assert list(arbiter.holders) == ['navigate-12']


def test_a_lower_priority_cannot_preempt_and_the_holder_goes_on() -> None:
    arbiter = arbiter_with(claim('navigate-12', 'base', priority=5))
    decision = arbiter.decide(claim('spin-4', 'base', priority=1), OnConflict.PREEMPT)
    assert decision.verdict is Verdict.REFUSE
    assert decision.error_code is ErrorCode.PREEMPTION_REFUSED
    assert decision.reason == "refused: priority 1 is below navigate-12's 5, which holds base"
    assert decision.preemptions == ()
    assert list(arbiter.holders) == ['navigate-12']
    assert not arbiter.is_queued('spin-4')


def test_the_refusal_names_the_strongest_holder() -> None:
    arbiter = arbiter_with(claim('drive', 'base', priority=2), claim('grip', 'arm', priority=6))
    decision = arbiter.decide(claim('pick', 'base', 'arm', priority=1), OnConflict.PREEMPT)
    assert decision.reason == "refused: priority 1 is below grip's 6, which holds arm"


def test_a_higher_priority_preempts_the_holder_with_the_words_the_victim_keeps() -> None:
    arbiter = arbiter_with(claim('navigate-12', 'base', priority=5))
    decision = arbiter.decide(claim('dock-3', 'base', priority=7), OnConflict.PREEMPT)
    assert decision.verdict is Verdict.START
    assert decision.reason == 'pre-empts navigate-12 (priority 5)'
    [preemption] = decision.preemptions
    assert preemption.victim.task_id == 'navigate-12'
    assert preemption.reason == 'cancelled: pre-empted by dock-3 (priority 7) for base'
    assert list(arbiter.holders) == ['dock-3']


def test_an_equal_priority_preempts_every_holder_it_conflicts_with() -> None:
    arbiter = arbiter_with(
        claim('drive', 'base', priority=3),
        claim('grip', 'arm', priority=3),
        claim('photo', 'camera', priority=9),
    )
    decision = arbiter.decide(claim('pick', 'base', 'arm', priority=3), OnConflict.PREEMPT)
    assert decision.verdict is Verdict.START
    assert {p.victim.task_id: p.reason for p in decision.preemptions} == {
        'drive': 'cancelled: pre-empted by pick (priority 3) for base',
        'grip': 'cancelled: pre-empted by pick (priority 3) for arm',
    }
    assert decision.reason == 'pre-empts drive (priority 3), grip (priority 3)'
    assert sorted(arbiter.holders) == ['photo', 'pick']


def test_reject_refuses_with_resource_busy() -> None:
    arbiter = arbiter_with(claim('navigate-12', 'base', priority=5))
    decision = arbiter.decide(claim('dock-3', 'base', priority=9), OnConflict.REJECT)
    assert decision.verdict is Verdict.REFUSE
    assert decision.error_code is ErrorCode.RESOURCE_BUSY
    assert decision.reason == 'refused: navigate-12 (priority 5), which holds base'
    assert list(arbiter.holders) == ['navigate-12']


def test_beyond_max_queued_a_queue_request_is_refused_with_queue_full() -> None:
    arbiter = arbiter_with(claim('navigate-12', 'base', priority=5), max_queued=1)
    assert arbiter.decide(claim('dock-3', 'base'), OnConflict.QUEUE).verdict is Verdict.QUEUE
    decision = arbiter.decide(claim('spin-4', 'base'), OnConflict.QUEUE)
    assert decision.verdict is Verdict.REFUSE
    assert decision.error_code is ErrorCode.QUEUE_FULL
    assert decision.reason == (
        'refused: navigate-12 (priority 5), which holds base; dock-3 (priority 0), queued for '
        'base, and the queue is full (max_queued 1)'
    )
    assert ids(arbiter.queued) == ['dock-3']


def test_preempt_is_refused_when_a_task_of_at_least_its_priority_is_queued_first() -> None:
    arbiter = arbiter_with(claim('navigate-12', 'base', priority=1))
    arbiter.decide(claim('dock-3', 'base', priority=5), OnConflict.QUEUE)
    decision = arbiter.decide(claim('spin-4', 'base', priority=5), OnConflict.PREEMPT)
    assert decision.verdict is Verdict.REFUSE
    assert decision.error_code is ErrorCode.PREEMPTION_REFUSED
    assert decision.reason == 'refused: dock-3 (priority 5) is queued first for base'
    assert list(arbiter.holders) == ['navigate-12']


def test_a_free_resource_wanted_by_a_queued_task_of_at_least_its_priority_is_not_taken() -> None:
    arbiter = arbiter_with(claim('drive', 'base'))
    arbiter.decide(claim('pick', 'base', 'arm', priority=2), OnConflict.QUEUE)
    decision = arbiter.decide(claim('wave', 'arm', priority=2), OnConflict.QUEUE)
    assert decision.verdict is Verdict.QUEUE
    assert decision.reason == 'queued behind pick (priority 2), queued for arm'
    assert decision.position == 2


def test_a_higher_priority_takes_a_free_resource_a_lower_queued_task_waits_for() -> None:
    arbiter = arbiter_with(claim('drive', 'base'))
    arbiter.decide(claim('pick', 'base', 'arm', priority=2), OnConflict.QUEUE)
    assert arbiter.decide(claim('wave', 'arm', priority=3), OnConflict.QUEUE).verdict is (
        Verdict.START
    )
    assert sorted(arbiter.holders) == ['drive', 'wave']


# ---- the queue: order, release, withdrawal, priority changes -----------------------------------


def test_the_queue_is_served_by_priority_then_arrival() -> None:
    arbiter = arbiter_with(claim('drive', 'base'))
    for task_id, priority in [('a', 0), ('b', 2), ('c', 2), ('d', 1)]:
        arbiter.decide(claim(task_id, 'base', priority=priority), OnConflict.QUEUE)
    assert ids(arbiter.queued) == ['b', 'c', 'd', 'a']
    assert [arbiter.position(task_id) for task_id in 'abcd'] == [4, 1, 2, 3]
    assert arbiter.position('drive') == 0
    assert ids(arbiter.release('drive')) == ['b']
    assert ids(arbiter.release('b')) == ['c']
    assert ids(arbiter.release('c')) == ['d']
    assert ids(arbiter.release('d')) == ['a']
    assert ids(arbiter.release('a')) == []
    assert arbiter.holders == {}


def test_a_release_starts_every_queued_task_it_frees_in_queue_order() -> None:
    arbiter = arbiter_with(claim('pick', 'base', 'arm', 'camera'))
    arbiter.decide(claim('drive', 'base', priority=1), OnConflict.QUEUE)
    arbiter.decide(claim('wave', 'arm'), OnConflict.QUEUE)
    arbiter.decide(claim('look', 'camera', priority=2), OnConflict.QUEUE)
    assert ids(arbiter.release('pick')) == ['look', 'drive', 'wave']


def test_a_queued_task_starts_past_one_ahead_that_wants_none_of_its_resources() -> None:
    arbiter = arbiter_with(claim('drive', 'base'), claim('grip', 'arm'))
    arbiter.decide(claim('dock', 'base', priority=5), OnConflict.QUEUE)
    arbiter.decide(claim('wave', 'arm'), OnConflict.QUEUE)
    assert ids(arbiter.release('grip')) == ['wave']
    assert ids(arbiter.queued) == ['dock']


def test_a_queued_task_waits_while_one_ahead_wants_one_of_its_resources() -> None:
    arbiter = arbiter_with(claim('drive', 'base'), claim('grip', 'arm'))
    arbiter.decide(claim('pick', 'base', 'arm', priority=5), OnConflict.QUEUE)
    arbiter.decide(claim('wave', 'arm'), OnConflict.QUEUE)
    assert ids(arbiter.release('grip')) == []
    assert ids(arbiter.release('drive')) == ['pick']
    assert ids(arbiter.queued) == ['wave']


def test_releasing_a_queued_task_withdraws_it_and_may_let_the_next_start() -> None:
    arbiter = arbiter_with(claim('drive', 'base'), claim('grip', 'arm'))
    arbiter.decide(claim('pick', 'base', 'arm', priority=5), OnConflict.QUEUE)
    arbiter.decide(claim('wave', 'arm'), OnConflict.QUEUE)
    arbiter.decide(claim('look', 'camera', 'base'), OnConflict.QUEUE)
    assert ids(arbiter.release('grip')) == []
    assert ids(arbiter.release('pick')) == ['wave']
    assert not arbiter.is_queued('pick')
    assert arbiter.position('look') == 1
    assert sorted(arbiter.holders) == ['drive', 'wave']


def test_releasing_an_unknown_or_ended_id_changes_nothing() -> None:
    arbiter = arbiter_with(claim('drive', 'base'))
    arbiter.decide(claim('dock', 'base'), OnConflict.QUEUE)
    assert arbiter.release('nope') == []
    assert list(arbiter.holders) == ['drive']
    assert ids(arbiter.queued) == ['dock']


def test_reprioritize_moves_a_queued_task() -> None:
    arbiter = arbiter_with(claim('drive', 'base'))
    for task_id in 'abc':
        arbiter.decide(claim(task_id, 'base'), OnConflict.QUEUE)
    assert arbiter.reprioritize('c', 4) == []
    assert ids(arbiter.queued) == ['c', 'a', 'b']
    assert arbiter.reprioritize('c', 0) == []
    assert ids(arbiter.queued) == ['a', 'b', 'c']
    assert arbiter.queued[2].priority == 0


def test_lowering_a_queued_priority_lets_the_tasks_it_held_back_start() -> None:
    arbiter = arbiter_with(claim('drive', 'base'))
    arbiter.decide(claim('pick', 'base', 'arm', priority=2), OnConflict.QUEUE)
    arbiter.decide(claim('wave', 'arm', priority=1), OnConflict.QUEUE)
    assert ids(arbiter.reprioritize('pick', 0) or []) == ['wave']
    assert ids(arbiter.queued) == ['pick']


def test_reprioritize_a_holder_changes_who_may_preempt_it() -> None:
    arbiter = arbiter_with(claim('drive', 'base', priority=1))
    assert arbiter.reprioritize('drive', 8) == []
    decision = arbiter.decide(claim('dock', 'base', priority=5), OnConflict.PREEMPT)
    assert decision.reason == "refused: priority 5 is below drive's 8, which holds base"


def test_reprioritize_an_id_that_holds_nothing_and_is_not_queued_is_none() -> None:
    assert arbiter_with(claim('drive', 'base')).reprioritize('nope', 3) is None


def test_blockers_name_the_holders_and_what_they_share() -> None:
    arbiter = arbiter_with(claim('drive', 'base'), claim('grip', 'arm'), claim('look', 'camera'))
    found = arbiter.blockers(claim('pick', 'base', 'arm', 'gripper'))
    assert {holder.task_id: shared for holder, shared in found} == {
        'drive': frozenset({'base'}),
        'grip': frozenset({'arm'}),
    }


# ---- pre-empted tasks until they have ended -----------------------------------------------------


def test_a_preempted_task_is_still_ending_for_others_until_it_is_released() -> None:
    arbiter = arbiter_with(claim('pick', 'base', 'arm'))
    arbiter.decide(claim('dock', 'base', priority=1), OnConflict.PREEMPT)
    assert list(arbiter.displaced) == ['pick']
    wave = claim('wave', 'arm')
    assert arbiter.decide(wave, OnConflict.REJECT) == Decision(Verdict.START)
    assert ids(arbiter.still_ending(wave)) == ['pick']
    assert arbiter.still_ending(claim('look', 'camera')) == []
    assert arbiter.release('pick') == []
    assert arbiter.still_ending(wave) == []
    assert arbiter.displaced == {}


def test_a_task_preempting_a_preemptor_that_never_started_waits_for_the_first_victim() -> None:
    arbiter = arbiter_with(claim('drive', 'base'))
    arbiter.decide(claim('dock', 'base'), OnConflict.PREEMPT)
    spin = claim('spin', 'base')
    assert ids([p.victim for p in arbiter.decide(spin, OnConflict.PREEMPT).preemptions]) == ['dock']
    assert ids(arbiter.still_ending(spin)) == ['drive', 'dock']


def test_a_victim_whose_preemptor_gave_up_first_holds_its_resources_again() -> None:
    arbiter = arbiter_with(claim('drive', 'base', 'arm'))
    arbiter.decide(claim('dock', 'base'), OnConflict.PREEMPT)
    assert arbiter.reinstate('drive')  # before the pre-emptor's release, as the node does it
    assert arbiter.release('dock') == []
    assert sorted(arbiter.holders) == ['drive']
    assert arbiter.displaced == {}
    refused = arbiter.decide(claim('wave', 'arm'), OnConflict.REJECT)
    assert refused.reason == 'refused: drive (priority 0), which holds arm'


def test_a_victim_is_not_reinstated_when_another_task_took_one_of_its_resources() -> None:
    arbiter = arbiter_with(claim('drive', 'base', 'arm'))
    arbiter.decide(claim('dock', 'base'), OnConflict.PREEMPT)
    arbiter.decide(claim('wave', 'arm'), OnConflict.PREEMPT)
    assert not arbiter.reinstate('drive')
    assert list(arbiter.displaced) == ['drive']
    assert not arbiter.reinstate('nope')


# ---- missions: a subtask uses what its missions hold -------------------------------------------


def test_a_subtask_may_use_what_its_mission_holds() -> None:
    arbiter = arbiter_with(claim('patrol', 'base', priority=2))
    decision = arbiter.decide(claim('leg-1', 'base', parent_id='patrol'), OnConflict.REJECT)
    assert decision == Decision(Verdict.START)
    assert sorted(arbiter.holders) == ['leg-1', 'patrol']


def test_a_subtask_of_a_subtask_may_use_what_the_outer_mission_holds() -> None:
    arbiter = arbiter_with(claim('patrol', 'base'), claim('round', parent_id='patrol'))
    decision = arbiter.decide(claim('leg-1', 'base', parent_id='round'), OnConflict.REJECT)
    assert decision.verdict is Verdict.START


def test_a_subtask_still_conflicts_with_others_and_with_its_siblings() -> None:
    arbiter = arbiter_with(claim('patrol', 'base'), claim('grip', 'arm'))
    refused = arbiter.decide(claim('pick', 'base', 'arm', parent_id='patrol'), OnConflict.REJECT)
    assert refused.reason == 'refused: grip (priority 0), which holds arm'
    assert arbiter.decide(
        claim('leg-1', 'base', parent_id='patrol'), OnConflict.REJECT
    ).verdict is (Verdict.START)
    sibling = arbiter.decide(claim('leg-2', 'base', parent_id='patrol'), OnConflict.REJECT)
    assert sibling.reason == 'refused: leg-1 (priority 0), which holds base'


def test_a_task_queued_for_the_missions_resource_does_not_hold_back_its_subtasks() -> None:
    arbiter = arbiter_with(claim('patrol', 'base'))
    assert arbiter.decide(claim('dock', 'base', priority=5), OnConflict.QUEUE).position == 1
    assert arbiter.decide(claim('leg-1', 'base', parent_id='patrol'), OnConflict.PREEMPT) == (
        Decision(Verdict.START)
    )
    assert ids(arbiter.release('leg-1')) == []
    assert ids(arbiter.release('patrol')) == ['dock']


def test_a_queued_subtask_is_not_held_back_by_a_task_waiting_for_its_mission() -> None:
    arbiter = arbiter_with(claim('patrol', 'base'), claim('look', 'camera'))
    arbiter.decide(claim('dock', 'base', priority=5), OnConflict.QUEUE)
    queued = arbiter.decide(claim('snap', 'base', 'camera', parent_id='patrol'), OnConflict.QUEUE)
    assert queued.reason == 'queued behind look (priority 0), which holds camera'
    assert ids(arbiter.release('look')) == ['snap']
    assert ids(arbiter.queued) == ['dock']


def test_a_queued_sibling_keeps_its_place_for_the_missions_resource() -> None:
    arbiter = arbiter_with(claim('patrol', 'base'), claim('look', 'camera'))
    arbiter.decide(claim('snap', 'base', 'camera', parent_id='patrol'), OnConflict.QUEUE)
    decision = arbiter.decide(claim('leg-1', 'base', parent_id='patrol'), OnConflict.QUEUE)
    assert decision.reason == 'queued behind snap (priority 0), queued for base'
    assert ids(arbiter.release('look')) == ['snap']


# ---- the original's rules, with no resources declared ------------------------------------------


def test_implied_resources() -> None:
    assert implied_resources(NAVIGATE, ['base'], blocking=True, reentrant=False) == {
        'base',
        BLOCKING,
        task_slot(NAVIGATE),
    }
    assert implied_resources(PHOTO, [], blocking=False, reentrant=True) == frozenset()
    assert resource_words({task_slot(NAVIGATE), BLOCKING, 'base'}) == 'base'
    assert resource_words({task_slot(NAVIGATE), BLOCKING}) == (
        'the blocking slot, the one goal slot of navigation/navigate_to_pose'
    )


def test_a_blocking_task_preempts_the_previous_blocking_one() -> None:
    arbiter = arbiter_with(declared('nav-1', NAVIGATE, blocking=True))
    decision = arbiter.decide(declared('dock-1', DOCK, blocking=True), OnConflict.PREEMPT)
    assert decision.verdict is Verdict.START
    [preemption] = decision.preemptions
    assert preemption.victim.task_id == 'nav-1'
    assert preemption.reason == 'cancelled: pre-empted by dock-1 (priority 0) for the blocking slot'
    assert list(arbiter.holders) == ['dock-1']


def test_a_second_goal_of_a_single_goal_task_preempts_the_first() -> None:
    arbiter = arbiter_with(declared('nav-1', NAVIGATE))
    decision = arbiter.decide(declared('nav-2', NAVIGATE), OnConflict.PREEMPT)
    [preemption] = decision.preemptions
    assert preemption.victim.task_id == 'nav-1'
    assert preemption.reason == (
        'cancelled: pre-empted by nav-2 (priority 0) for the one goal slot of ' + NAVIGATE
    )


def test_a_blocking_reentrant_task_still_preempts_its_own_earlier_goal() -> None:
    arbiter = arbiter_with(declared('dock-1', DOCK, blocking=True, reentrant=True))
    decision = arbiter.decide(
        declared('dock-2', DOCK, blocking=True, reentrant=True), OnConflict.PREEMPT
    )
    assert ids([p.victim for p in decision.preemptions]) == ['dock-1']


@pytest.mark.parametrize('blocking_first', [False, True])
def test_reentrant_tasks_never_conflict_with_themselves(blocking_first: bool) -> None:
    arbiter = arbiter_with(declared('nav-1', NAVIGATE, blocking=blocking_first))
    for n in range(3):
        decision = arbiter.decide(declared(f'photo-{n}', PHOTO, reentrant=True), OnConflict.REJECT)
        assert decision == Decision(Verdict.START)
    assert len(arbiter.holders) == 4


def test_different_single_goal_tasks_that_are_not_blocking_run_side_by_side() -> None:
    arbiter = arbiter_with(declared('nav-1', NAVIGATE), declared('photo-1', PHOTO))
    assert arbiter.decide(declared('dock-1', DOCK), OnConflict.REJECT) == Decision(Verdict.START)


def test_a_blocking_task_does_not_conflict_with_a_task_that_is_not_blocking() -> None:
    arbiter = arbiter_with(declared('photo-1', PHOTO))
    decision = arbiter.decide(declared('dock-1', DOCK, blocking=True), OnConflict.REJECT)
    assert decision == Decision(Verdict.START)


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
