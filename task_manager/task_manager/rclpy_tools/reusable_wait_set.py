"""An rcl wait set made once for a list of entities and filled again for each wait.

rclpy's executor makes its wait set anew at every turn: it filters every entity of its nodes
through its callback group (a weak reference and a set lookup each, for a mutually exclusive
group), enters each handle through an ExitStack, counts the entities of each waitable, makes
the rcl wait set, and after the wait asks every entity whether its pointer is among the ready
ones. Here that is done once per node and kind of entity for as long as that node's list of
them stays the same (a node that makes and destroys a timer per task makes its timers' part
again, nothing else); each wait only enters the handles (as rclpy does, so that none is
destroyed while rcl waits on it), fills the wait set and reads back the few that are ready.
"""

from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass
from itertools import chain
from typing import Any

from rclpy.callback_groups import (
    CallbackGroup,
    MutuallyExclusiveCallbackGroup,
    ReentrantCallbackGroup,
)
from rclpy.context import Context
from rclpy.exceptions import InvalidHandle
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node

# the order in which rclpy handles the ready entities of a node, after every waitable
KINDS = ('timer', 'subscription', 'guard_condition', 'client', 'service')
# where each kind of entity is counted, in the order rcl's WaitSet takes the counts (subscriptions,
# guard conditions, timers, clients, services, events)
_INDEX = {'subscription': 0, 'guard_condition': 1, 'timer': 2, 'client': 3, 'service': 4}
_COUNTS = (
    'num_subscriptions',
    'num_guard_conditions',
    'num_timers',
    'num_clients',
    'num_services',
    'num_events',
)
# places of each kind a new rcl wait set has beyond those it is made for
SPARE = 8
# callback groups whose answer to can_execute is the same for all their entities
_GROUP_WIDE = (MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup)
_Groups = dict[int, tuple[CallbackGroup | None, Any]]


@dataclass(frozen=True)
class NodeEntities:
    """What a wait set waits on for one node, in rclpy's order."""

    node: Node
    timers: list[Any]
    subscriptions: list[Any]
    guards: list[GuardCondition]
    clients: list[Any]
    services: list[Any]
    waitables: list[Any]

    @classmethod
    def of(cls, node: Node) -> 'NodeEntities':
        return cls(
            node,
            list(node.timers),
            list(node.subscriptions),
            list(node.guards),
            list(node.clients),
            list(node.services),
            list(node.waitables),
        )

    def executable(self, can_execute: Callable[[Any], bool]) -> 'NodeEntities':
        """Those entities the executor may wait on now."""

        def kept(listed: list[Any]) -> list[Any]:
            return [entity for entity in listed if can_execute(entity)]

        return NodeEntities(
            self.node,
            kept(self.timers),
            kept(self.subscriptions),
            kept(self.guards),
            kept(self.clients),
            kept(self.services),
            kept(self.waitables),
        )

    def by_kind(self) -> Iterator[tuple[str, list[Any]]]:
        """Each kind with its entities, rclpy's order, the waitables last."""
        lists = (self.timers, self.subscriptions, self.guards, self.clients, self.services)
        yield from zip(KINDS, lists, strict=True)
        yield 'waitable', self.waitables


@dataclass(frozen=True)
class Ready:
    """An entity the wait found ready, with its node."""

    kind: str  # one of KINDS, or 'waitable'
    entity: Any
    node: Node


class _Part:
    """What a wait set needs of one node's entities of one kind, kept while that list stays
    the same (an entity destroyed meanwhile left out, as rclpy's wait leaves it out)."""

    def __init__(self, node: Node, node_index: int, kind: str, listed: list[Any]) -> None:
        self.node, self.node_index, self.kind, self.listed = node, node_index, kind, listed
        self.handles: list[Any] = []  # what the wait enters: handles, or the waitables
        # key: (kind, rcl pointer), value: its place in rclpy's order of handling, and it
        self.order: dict[tuple[str, int], tuple[tuple[int, int, int], Ready]] = {}
        self.groups: _Groups = {}
        self.entities: list[Any] = []
        self.waitables: list[tuple[Any, Node]] = []
        self.count = [0] * len(_COUNTS)
        kind_index = KINDS.index(kind) if kind in KINDS else len(KINDS)
        for position, entity in enumerate(listed):
            try:
                self._add(entity, (node_index, kind_index, position))
            except InvalidHandle:
                continue

    def _add(self, entity: Any, place: tuple[int, int, int]) -> None:
        if self.kind == 'waitable':
            with entity:
                numbers = entity.get_num_entities()
            self.count = [
                n + getattr(numbers, name) for n, name in zip(self.count, _COUNTS, strict=True)
            ]
            self.handles.append(entity)
            self.waitables.append((entity, self.node))
        else:
            with entity.handle:
                pointer = entity.handle.pointer
            self.count[_INDEX[self.kind]] += 1
            self.handles.append(entity.handle)
            self.order[self.kind, pointer] = (place, Ready(self.kind, entity, self.node))
        self.entities.append(entity)
        group = entity.callback_group
        if group is not None and isinstance(group, _GROUP_WIDE):
            self.groups[id(group)] = (group, entity)
        else:  # another kind of group answers for each entity
            self.groups[id(entity)] = (group, entity)

    def still_for(self, node: Node, node_index: int, listed: list[Any]) -> bool:
        return self.node is node and self.node_index == node_index and self.listed == listed


class ReusableWaitSet:
    """The wait set of fixed entities (and the executor's own guards), filled for each wait.

    Made from the `previous` one, it reuses the parts of the lists that stayed the same, and
    its rcl wait set when large enough (each is made with SPARE places of each kind to spare).
    """

    def __init__(
        self,
        entities: list[NodeEntities],
        own_guards: list[GuardCondition],
        context: Context,
        previous: 'ReusableWaitSet | None' = None,
    ) -> None:
        self.entities = entities
        self.own_guards = own_guards
        if context.handle is None:
            raise RuntimeError('the context has no handle: was it initialised?')
        self._context_handle = context.handle
        known = previous._parts if previous is not None else {}
        self._parts: dict[tuple[int, str], _Part] = {}
        for node_index, node_entities in enumerate(entities):
            node = node_entities.node
            for kind, listed in node_entities.by_kind():
                part = known.get((id(node), kind))
                if part is None or not part.still_for(node, node_index, listed):
                    part = _Part(node, node_index, kind, listed)
                self._parts[id(node), kind] = part
        parts = list(self._parts.values())
        guard_handles = [guard.handle for guard in own_guards]
        self._handles = [*chain.from_iterable(part.handles for part in parts), *guard_handles]
        self._order: dict[tuple[str, int], tuple[tuple[int, int, int], Ready]] = {}
        groups: _Groups = {}
        for part in parts:
            self._order.update(part.order)
            groups.update(part.groups)
        self._groups = list(groups.values())
        self._entities = list(chain.from_iterable(part.entities for part in parts))
        self._waitables = list(chain.from_iterable(part.waitables for part in parts))
        count = [0] * len(_COUNTS)
        count[_INDEX['guard_condition']] = len(own_guards)
        for part in parts:
            count = [have + more for have, more in zip(count, part.count, strict=True)]
        self._capacity, self._wait_set = _rcl_wait_set(count, self._context_handle, previous)
        add: dict[str, Callable[[Any], object]] = {
            'timer': self._wait_set.add_timer,
            'subscription': self._wait_set.add_subscription,
            'guard_condition': self._wait_set.add_guard_condition,
            'client': self._wait_set.add_client,
            'service': self._wait_set.add_service,
        }
        self._adds = [(add[part.kind], part.handles) for part in parts if part.kind in add]
        self._adds.append((add['guard_condition'], guard_handles))

    def all_can_execute(self) -> bool:
        """Whether the executor may wait on every entity (none taken but not yet handled, no
        callback group busy): else the turn needs a wait set of those it may."""
        if any(entity._executor_event for entity in self._entities):
            return False
        return all(group is not None and group.can_execute(e) for group, e in self._groups)

    def wait(self, timeout_nsec: int) -> tuple[list[Ready], Generator[Ready, None, None]]:
        """Wait (rcl's timeout: -1 forever, 0 not at all); the ready entities, as two parts:
        the waitables' (to be handled before the handles are released, as rclpy does) and
        the others, in rclpy's order. The waitables' part is an iterator that releases the
        handles once exhausted or closed."""
        entered = self._enter()
        try:
            wait_set = self._wait_set
            wait_set.clear_entities()
            for add, handles in self._adds:
                for handle in handles:
                    add(handle)
            for waitable, _ in self._waitables:
                waitable.add_to_wait_set(wait_set)
            wait_set.wait(timeout_nsec)
            ready = self._ready(wait_set)
        except BaseException:
            _exit(entered)
            raise
        return ready, self._ready_waitables(entered)

    def _ready(self, wait_set: Any) -> list[Ready]:
        found = []
        order = self._order
        for kind in KINDS:
            for pointer in wait_set.get_ready_entities(kind):
                if (kind, pointer) in order:  # not the executor's own guards
                    found.append(order[kind, pointer])
        found.sort(key=lambda place: place[0])
        return [ready for _, ready in found]

    def _ready_waitables(self, entered: list[Any]) -> Generator[Ready, None, None]:
        try:
            for waitable, node in self._waitables:
                if waitable.is_ready(self._wait_set):
                    yield Ready('waitable', waitable, node)
        finally:
            _exit(entered)

    def _enter(self) -> list[Any]:
        """Enter every handle (and the context's); one destroyed since the wait set was made
        (from another thread) raises InvalidHandle once the others are released."""
        entered: list[Any] = []
        try:
            for handle in self._handles:
                handle.__enter__()
                entered.append(handle)
            self._context_handle.__enter__()
            entered.append(self._context_handle)
        except BaseException:
            _exit(entered)
            raise
        return entered


def _rcl_wait_set(
    count: list[int], context_handle: Any, previous: ReusableWaitSet | None
) -> tuple[list[int], Any]:
    """The previous rcl wait set if it has room for `count`, else one with SPARE places more of
    each kind; with its capacity."""
    if previous is not None and all(
        need <= room for need, room in zip(count, previous._capacity, strict=True)
    ):
        return previous._capacity, previous._wait_set
    subscriptions, guards, timers, clients, services, events = (need + SPARE for need in count)
    wait_set = _rclpy.WaitSet(
        subscriptions, guards, timers, clients, services, events, context_handle
    )
    return [subscriptions, guards, timers, clients, services, events], wait_set


def _exit(entered: list[Any]) -> None:
    for handle in reversed(entered):
        handle.__exit__(None, None, None)
