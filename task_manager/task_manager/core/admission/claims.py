"""The resources a task holds while it runs, and how they are named to an operator.

One model for every conflict rule: a task holds the resources its declaration lists, plus
two implicit ones that carry the original's rules. A blocking task holds BLOCKING, so it
conflicts with every other blocking task; a task that is not reentrant holds its own name's
slot, so a second goal of it conflicts with the first.
"""

from collections.abc import Iterable
from dataclasses import dataclass

BLOCKING = '@blocking'
_TASK_SLOT = '@task:'


def task_slot(task_name: str) -> str:
    """The implicit resource of a task that runs one goal at a time."""
    return _TASK_SLOT + task_name


def implied_resources(
    task_name: str, declared: Iterable[str], blocking: bool, reentrant: bool
) -> frozenset[str]:
    """Every resource a task of this declaration holds while it runs."""
    held = set(declared)
    if blocking:
        held.add(BLOCKING)
    if not reentrant:
        held.add(task_slot(task_name))
    return frozenset(held)


def resource_words(resources: Iterable[str]) -> str:
    """Resources as an operator reads them: the declared ones (`base, camera`); the implicit
    ones only when no declared one is shared (`the blocking slot`, `the one goal slot of X`)."""
    resources = sorted(resources)
    declared = [resource for resource in resources if not resource.startswith('@')]
    if declared:
        return ', '.join(declared)
    words = []
    for resource in resources:
        if resource == BLOCKING:
            words.append('the blocking slot')
        elif resource.startswith(_TASK_SLOT):
            words.append(f'the one goal slot of {resource[len(_TASK_SLOT) :]}')
    return ', '.join(words)


@dataclass
class Claim:
    """One task's bid for its resources: what it holds, how much it matters, when it came."""

    task_id: str
    task_name: str
    resources: frozenset[str]
    priority: int = 0
    parent_id: str = ''
    """The mission it runs in: a subtask may use what its missions hold."""
    arrival: int = 0
    """Set by the arbiter: the order of arrival, for ties of priority."""

    def label(self) -> str:
        return f'{self.task_id} (priority {self.priority})'
