"""Deadlines: every timeout on one clock, the earliest first, replaced or cleared by key."""

import functools

from hypothesis import given
from hypothesis import strategies as st

from task_manager.core.admission.deadlines import Deadlines


def test_due_actions_come_earliest_first_and_are_forgotten() -> None:
    deadlines = Deadlines()
    fired: list[str] = []
    deadlines.set('b', 2.0, lambda: fired.append('b'))
    deadlines.set('a', 1.0, lambda: fired.append('a'))
    deadlines.set('c', 3.0, lambda: fired.append('c'))

    for action in deadlines.pop_due(2.5):
        action()

    assert fired == ['a', 'b']
    assert deadlines.next_at() == 3.0
    assert len(deadlines) == 1


def test_setting_a_key_again_replaces_its_deadline_and_clear_drops_it() -> None:
    deadlines = Deadlines()
    fired: list[str] = []
    deadlines.set('feedback', 1.0, lambda: fired.append('first'))
    deadlines.set('feedback', 5.0, lambda: fired.append('second'))
    deadlines.set('run', 2.0, lambda: fired.append('run'))
    deadlines.clear('run')

    assert deadlines.next_at() == 5.0
    for action in deadlines.pop_due(10.0):
        action()
    assert fired == ['second']
    assert deadlines.next_at() is None


@given(st.lists(st.tuples(st.integers(0, 5), st.floats(0, 100)), max_size=30), st.floats(0, 100))
def test_only_the_latest_deadline_of_each_key_fires_once_when_due(
    sets: list[tuple[int, float]], now: float
) -> None:
    deadlines = Deadlines()
    fired: list[int] = []
    latest: dict[int, float] = {}
    for key, at in sets:
        deadlines.set(key, at, functools.partial(fired.append, key))
        latest[key] = at

    for action in deadlines.pop_due(now):
        action()

    assert sorted(fired) == sorted(key for key, at in latest.items() if at <= now)
    assert len(deadlines) == sum(1 for at in latest.values() if at > now)


def test_deadlines_cleared_long_before_they_are_due_are_not_kept() -> None:
    """A bounded wait that ends early clears its deadline: 10,000 of them, each due in two
    minutes, must not stay in memory until then."""
    deadlines = Deadlines()
    fired: list[int] = []
    deadlines.set('kept', 200.0, lambda: fired.append(-1))
    for key in range(10_000):
        deadlines.set(key, 120.0, functools.partial(fired.append, key))
        deadlines.clear(key)
    assert len(deadlines) == 1 and deadlines.heap_size() <= 2 + 64
    assert deadlines.next_at() == 200.0
    for action in deadlines.pop_due(300.0):
        action()
    assert fired == [-1]
