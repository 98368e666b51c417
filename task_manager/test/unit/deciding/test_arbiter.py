"""Tests of the arbiter: who starts, who waits, who is refused or pre-empted, and why."""

import pytest

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
