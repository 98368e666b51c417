"""Tests of the registry of active tasks and of the conflict rules between them."""

import itertools
from typing import Any

import pytest
from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, rule

from task_manager.core.errors import TaskRequestError
from task_manager.core.registry import TaskRegistry
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.core.task import TaskRecord
from task_manager.core.task_spec import InterfaceName, TaskKind, TaskSpec


def make_spec(name: str = 'fib', **options: Any) -> TaskSpec:
    interface = InterfaceName('test_msgs', TaskKind.ACTION, 'Fibonacci')
    return TaskSpec(task_name=name, topic=f'/{name}', interface=interface, **options)


def make_record(
    task_id: str, spec: TaskSpec | None = None, status: TaskStatus = TaskStatus.RECEIVED
) -> TaskRecord:
    record = TaskRecord(task_id=task_id, spec=spec or make_spec(), source='test', received_at=1.0)
    if status is TaskStatus.IN_PROGRESS:
        record.mark_started(now=2.0)
    return record


def registry_of(*records: TaskRecord) -> TaskRegistry:
    registry = TaskRegistry()
    for record in records:
        registry.admit(record)
    return registry


def ids(records: Any) -> list[str]:
    return [record.task_id for record in records]


# ---- admit / remove / get --------------------------------------------------------------------


@pytest.mark.parametrize('first_status', [TaskStatus.RECEIVED, TaskStatus.IN_PROGRESS])
def test_admit_rejects_a_duplicate_active_id_and_leaves_the_first_untouched(
    first_status: TaskStatus,
) -> None:
    first = make_record('t1', make_spec('fib'), first_status)
    registry = registry_of(first)
    with pytest.raises(TaskRequestError) as raised:
        registry.admit(make_record('t1', make_spec('other')))
    assert raised.value.error_code is ErrorCode.DUPLICATE_TASK_ID
    assert "'t1'" in str(raised.value)
    assert registry.get('t1') is first
    assert len(registry) == 1
    assert first.status is first_status
    assert first.cancel_reason is None
    assert first.ended_at is None


def test_an_id_can_be_reused_after_remove() -> None:
    first = make_record('t1')
    registry = registry_of(first)
    registry.remove('t1')
    assert registry.get('t1') is None
    second = make_record('t1', make_spec('other'))
    registry.admit(second)
    assert registry.get('t1') is second
    assert len(registry) == 1


def test_get_and_remove_of_an_unknown_id() -> None:
    registry = registry_of(make_record('t1'))
    assert registry.get('nope') is None
    registry.remove('nope')  # nothing to remove is not an error
    assert ids(registry) == ['t1']


def test_iteration_is_in_insertion_order() -> None:
    registry = registry_of(*(make_record(task_id, make_spec(task_id)) for task_id in 'cab'))
    assert ids(registry) == ['c', 'a', 'b']
    registry.remove('a')
    registry.admit(make_record('a', make_spec('a')))
    assert ids(registry) == ['c', 'b', 'a']
    assert len(registry) == 3


def test_removing_while_iterating_is_safe() -> None:
    registry = registry_of(*(make_record(task_id, make_spec(task_id)) for task_id in 'abc'))
    seen = []
    for record in registry:
        seen.append(record.task_id)
        registry.remove(record.task_id)
    assert seen == ['a', 'b', 'c']
    assert len(registry) == 0


# ---- conflicts -------------------------------------------------------------------------------


@pytest.mark.parametrize('status', [TaskStatus.RECEIVED, TaskStatus.IN_PROGRESS])
def test_a_non_reentrant_task_conflicts_with_active_tasks_of_its_name(status: TaskStatus) -> None:
    spec = make_spec('fib')
    old = make_record('old', spec, status)
    registry = registry_of(old, make_record('other', make_spec('other')))
    new = make_record('new', spec)
    registry.admit(new)
    assert registry.conflicts_of(spec, 'new') == [old]


def test_a_reentrant_task_does_not_conflict_with_its_own_name() -> None:
    spec = make_spec('fib', reentrant=True)
    registry = registry_of(
        make_record('g1', spec, TaskStatus.IN_PROGRESS),
        make_record('g2', spec),
        make_record('g3', spec),
    )
    assert registry.conflicts_of(spec, 'g3') == []
    assert registry.conflicts_of(spec, 'g4') == []


def test_a_non_blocking_task_does_not_conflict_with_other_names() -> None:
    registry = registry_of(
        make_record('b', make_spec('blocker', blocking=True), TaskStatus.IN_PROGRESS),
        make_record('s', make_spec('stoppable', cancel_on_stop=True)),
        make_record('p', make_spec('plain')),
    )
    assert registry.conflicts_of(make_spec('fib'), 'new') == []


def test_a_blocking_task_conflicts_with_every_other_blocking_task_of_any_name() -> None:
    blocking_x = make_record('x', make_spec('x', blocking=True), TaskStatus.IN_PROGRESS)
    plain_y = make_record('y', make_spec('y'), TaskStatus.IN_PROGRESS)
    blocking_z = make_record('z', make_spec('z', blocking=True, reentrant=True))
    reentrant_w = make_record('w', make_spec('w', reentrant=True))
    registry = registry_of(blocking_x, plain_y, blocking_z, reentrant_w)
    new_spec = make_spec('fib', blocking=True, reentrant=True)
    assert registry.conflicts_of(new_spec, 'new') == [blocking_x, blocking_z]


def test_a_blocking_reentrant_task_still_runs_only_one_goal() -> None:
    # "only one blocking task at a time in the whole system" (INTERFACES.md, Parameters)
    spec = make_spec('fib', blocking=True, reentrant=True)
    first = make_record('g1', spec, TaskStatus.IN_PROGRESS)
    registry = registry_of(first, make_record('g2', spec))
    assert registry.conflicts_of(spec, 'g2') == [first]


def test_both_rules_together_list_each_conflict_once_in_order() -> None:
    spec = make_spec('fib', blocking=True)
    same_name = make_record('a', spec)
    other_blocking = make_record('b', make_spec('other', blocking=True))
    registry = registry_of(same_name, make_record('c', make_spec('plain')), other_blocking)
    assert registry.conflicts_of(spec, 'new') == [same_name, other_blocking]


def test_a_task_never_conflicts_with_itself() -> None:
    spec = make_spec('fib', blocking=True)
    record = make_record('t1', spec)
    registry = registry_of(record)
    assert registry.conflicts_of(spec, 't1') == []
    assert registry.conflicts_of(spec, 't2') == [record]


# ---- stop and progress -----------------------------------------------------------------------


def test_cancelled_by_stop_returns_only_cancel_on_stop_tasks() -> None:
    stop_a = make_record('a', make_spec('a', cancel_on_stop=True), TaskStatus.IN_PROGRESS)
    keep_b = make_record('b', make_spec('b', blocking=True), TaskStatus.IN_PROGRESS)
    stop_c = make_record('c', make_spec('c', cancel_on_stop=True))
    registry = registry_of(stop_a, keep_b, stop_c)
    assert registry.cancelled_by_stop() == [stop_a, stop_c]
    assert registry_of(keep_b).cancelled_by_stop() == []


# ---- property: conflict resolution keeps the system consistent -------------------------------

specs = st.builds(
    make_spec,
    name=st.sampled_from(['nav', 'dock', 'arm', 'beep']),
    blocking=st.booleans(),
    reentrant=st.booleans(),
    cancel_on_stop=st.booleans(),
)


class ConflictResolution(RuleBasedStateMachine):
    """Tasks start (after cancelling their conflicts), run and end in any order."""

    def __init__(self) -> None:
        super().__init__()
        self.registry = TaskRegistry()
        self.specs: list[TaskSpec] = []
        self.model_ids: list[str] = []
        self.counter = itertools.count()

    @initialize(declared=st.lists(specs, min_size=1, max_size=4, unique_by=lambda s: s.task_name))
    def declare(self, declared: list[TaskSpec]) -> None:
        self.specs = declared

    @rule(index=st.integers(0, 3), reuse=st.booleans())
    def start_task(self, index: int, reuse: bool) -> None:
        spec = self.specs[index % len(self.specs)]
        task_id = self._free_id(reuse)
        record = make_record(task_id, spec)
        self.registry.admit(record)
        conflicts = self.registry.conflicts_of(spec, task_id)
        assert record not in conflicts
        for conflict in conflicts:
            self.registry.remove(conflict.task_id)
            self.model_ids.remove(conflict.task_id)
        self.model_ids.append(task_id)
        assert self.registry.get(task_id) is record

    @rule(index=st.integers(0, 20))
    def run_task(self, index: int) -> None:
        records = [r for r in self.registry if r.status is TaskStatus.RECEIVED]
        if records:
            records[index % len(records)].mark_started(now=5.0)

    @rule(index=st.integers(0, 20))
    def end_task(self, index: int) -> None:
        if self.model_ids:
            task_id = self.model_ids.pop(index % len(self.model_ids))
            self.registry.remove(task_id)

    @rule(index=st.integers(0, 20))
    def reuse_an_active_id(self, index: int) -> None:
        if not self.model_ids:
            return
        task_id = self.model_ids[index % len(self.model_ids)]
        active = self.registry.get(task_id)
        with pytest.raises(TaskRequestError) as raised:
            self.registry.admit(make_record(task_id, self.specs[0]))
        assert raised.value.error_code is ErrorCode.DUPLICATE_TASK_ID
        assert self.registry.get(task_id) is active

    def _free_id(self, reuse: bool) -> str:
        """A new id, or (with `reuse`) the smallest id not active now."""
        if reuse:
            for n in itertools.count():
                if f't{n}' not in self.model_ids:
                    return f't{n}'
        return f'u{next(self.counter)}'

    @invariant()
    def at_most_one_blocking_task(self) -> None:
        assert sum(record.spec.blocking for record in self.registry) <= 1

    @invariant()
    def at_most_one_task_per_non_reentrant_name(self) -> None:
        names = [r.task_name for r in self.registry if not r.spec.reentrant]
        assert len(names) == len(set(names))

    @invariant()
    def registry_matches_the_model(self) -> None:
        assert ids(self.registry) == self.model_ids
        assert len(self.registry) == len(self.model_ids)
        assert ids(self.registry.cancelled_by_stop()) == [
            r.task_id for r in self.registry if r.spec.cancel_on_stop
        ]


ConflictResolution.TestCase.settings = settings(
    max_examples=40, stateful_step_count=20, deadline=None
)
test_conflict_resolution = ConflictResolution.TestCase
