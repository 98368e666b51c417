"""Whether the client still hears the Task Manager after its process was held up.

A process stopped or starved for longer than the DDS lease (5 s, fastdds_discovery.xml) is
forgotten by the node's participant, or forgets it, and the two discover each other again when
it runs on. Measured with the VDA 5050 adapter stopped 9-11 s while the node published
thousands of event batches: in 4 of 5 stops that rediscovery stayed one-sided for good. The
node took the adapter's requests and ran them, and nothing of the node reached the adapter
again (no reply, no event, not even to a reader made afterwards); with a 60 s lease on every
participant it always heard the node again. The cause is inside Fast DDS; a new participant
(a new process) is heard at once.

The node held up past the lease does the same to the clients that were not: measured with the
node stopped 12 s, an old client heard it no more (in 5 of 6 stops) while a taskctl started
after it did at once.

So a process that must keep hearing the node (a gateway, a follow of taskctl) asks for the
check (`on_node_unheard`). A timer on the client's executor notices a turn late by
HELD_UP_SEC or more; the client then asks the node a question that any node answers at once
(GetTaskStates of no task, sent again while unanswered) and waits for the answer and for every
topic that reached the client before the hold-up to reach it again (HearingCheck). And once
the node's active list has not reached the client for LOST_SEC (lost, or not met since the
check began: a newcomer's participant now and then never matches the node's endpoints while
others started at the same moment do), a new participant of this process looks for the node,
again each LOOK_AGAIN_SEC while it is lost: one that sees it while the client still does not
SEEN_GRACE_SEC later means the client is deaf (LostNodeCheck).
Either way the listeners are told how many seconds it went on, and it is theirs to start a new
process (the gateways exit, for their supervisor to start them again).
"""

import queue
import threading
import time
from collections.abc import Callable, Set
from enum import Enum
from typing import Any

import rclpy
from rclpy.client import Client
from rclpy.context import Context
from rclpy.task import Future
from rclpy.timer import Timer
from task_manager_msgs.srv import GetTaskStates

from task_manager.client.connection import SERVICE_RETRY_SEC, Connection, client_node
from task_manager.client.listeners import Callback, Listeners
from task_manager.core.names import ACTIVE_TASKS_TOPIC, GET_TASK_STATES_SERVICE
from task_manager.rclpy_tools.log import NodeLog

CHECK_PERIOD_SEC = 1.0
"""How often the check's timer runs (only in a client asked for the check)."""
HELD_UP_SEC = 4.0
"""A turn of the timer this late: the process was held up. A hold-up of s seconds makes a turn
late by s - 1 to s: one that outlasts the 5 s lease is always seen."""
ANSWER_SEC = 10.0
"""How long after a hold-up the Task Manager has to be heard again: the lease, then a second
for the participants' announcements, with room for a node busy with a flood."""


LOST_SEC = 10.0
"""The node's active list not reaching the client this long: a new participant looks for it."""
LOOK_AGAIN_SEC = 30.0
"""How often the new participant looks again while the node stays lost."""
LOOK_SEC = 3.0
"""How long the new participant looks (a newcomer finds a node within a second or so)."""
SEEN_GRACE_SEC = 10.0
"""The time the client is given to find the node too, after the new participant saw it."""


class Step(Enum):
    """What a turn of a check asks of its client."""

    NOTHING = 'nothing'
    ASK = 'ask the Task Manager'
    LOOK = 'look for the Task Manager with a new participant'
    HEARD = 'heard again'
    UNHEARD = 'not heard again'


class HearingCheck:
    """The check's decisions, from the times of its turns (time.monotonic) and what reached
    the client; no ROS here."""

    def __init__(
        self,
        held_up_sec: float = HELD_UP_SEC,
        answer_sec: float = ANSWER_SEC,
        period_sec: float = CHECK_PERIOD_SEC,
    ) -> None:
        self.held_up_sec = held_up_sec
        self.answer_sec = answer_sec
        self.period_sec = period_sec
        """The time between two turns on time."""
        self.held_up_for = 0.0
        """How late the turn that began the last check came."""
        self._last_turn: float | None = None
        self._expected: Set[str] = frozenset()
        """The topics that reached the client at the last turn before a hold-up."""
        self._checking_since: float | None = None
        self._answered = False
        self._next_ask = 0.0
        self._retry_sec = SERVICE_RETRY_SEC

    @property
    def checking(self) -> bool:
        """Whether a check is under way (begun by a late turn, not concluded)."""
        return self._checking_since is not None

    @property
    def expecting(self) -> Set[str]:
        """The topics that must reach the client again after a hold-up."""
        return self._expected

    def turn(self, now: float, reaching: Set[str]) -> Step:
        """A turn of the timer at `now`; `reaching`: the topics that reach the client now."""
        late_by = 0.0 if self._last_turn is None else now - self._last_turn - self.period_sec
        self._last_turn = now
        if late_by >= self.held_up_sec and (self._expected or self.checking):
            self._checking_since, self.held_up_for, self._answered = now, late_by, False
            self._retry_sec = SERVICE_RETRY_SEC
            self._next_ask = now + self._retry_sec
            return Step.ASK
        if not self.checking:
            self._expected = frozenset(reaching)
            return Step.NOTHING
        if self._answered and self._expected <= reaching:
            self._checking_since = None
            self._expected = frozenset(reaching)
            return Step.HEARD
        if now - (self._checking_since or now) >= self.answer_sec:
            self._checking_since = None
            self._expected = frozenset(reaching)
            return Step.UNHEARD
        if not self._answered and now >= self._next_ask:
            self._retry_sec *= 2
            self._next_ask = now + self._retry_sec
            return Step.ASK
        return Step.NOTHING

    def reaching_changed(self, now: float, reaching: Set[str]) -> None:
        """The topics that reach the client changed at `now`: they are what must reach it
        again after a hold-up, unless the change came in one (a turn overdue by HELD_UP_SEC:
        the lease ran out meanwhile), or while a check is under way."""
        overdue = self._last_turn is not None and (
            now - self._last_turn >= self.period_sec + self.held_up_sec
        )
        if not (overdue or self.checking):
            self._expected = frozenset(reaching)

    def answered(self) -> None:
        """The Task Manager answered the check's question."""
        if self.checking:
            self._answered = True


class LostNodeCheck:
    """Whether a client that lost the node, or never met it, is deaf to it: decisions from
    the times of the check's turns, whether the node's active list reaches the client and
    what a new participant saw; no ROS here."""

    def __init__(
        self,
        lost_sec: float = LOST_SEC,
        look_again_sec: float = LOOK_AGAIN_SEC,
        grace_sec: float = SEEN_GRACE_SEC,
    ) -> None:
        self.lost_sec = lost_sec
        self.look_again_sec = look_again_sec
        self.grace_sec = grace_sec
        self.looking = False
        """Whether a new participant is looking for the node now."""
        self._lost_since: float | None = None
        self._next_look = 0.0
        self._seen_at: float | None = None

    def lost_for(self, now: float) -> float:
        """How long the node's active list has not reached the client (0 while it does)."""
        return 0.0 if self._lost_since is None else now - self._lost_since

    def turn(self, now: float, reaching: Set[str]) -> Step:
        """A turn at `now`; `reaching`: the topics that reach the client now."""
        if ACTIVE_TASKS_TOPIC in reaching:
            self.reaching_changed(reaching)
            return Step.NOTHING
        if self._lost_since is None:  # lost now, or not met since the check began
            self._lost_since, self._next_look = now, now + self.lost_sec
        if self._seen_at is not None and now - self._seen_at >= self.grace_sec:
            self._seen_at = None
            return Step.UNHEARD
        if not self.looking and self._seen_at is None and now >= self._next_look:
            self.looking, self._next_look = True, now + self.look_again_sec
            return Step.LOOK
        return Step.NOTHING

    def reaching_changed(self, reaching: Set[str]) -> None:
        """The topics that reach the client changed (between turns)."""
        if ACTIVE_TASKS_TOPIC in reaching:
            self._lost_since, self._seen_at = None, None

    def looked(self, now: float, seen: bool) -> None:
        """The new participant saw the node at `now`, or not."""
        self.looking = False
        if seen and self._lost_since is not None:
            self._seen_at = now


def node_seen_anew(timeout_sec: float = LOOK_SEC) -> bool:
    """Whether a new participant of this process (a context of its own) sees a publisher of
    the Task Manager's active list within `timeout_sec`; it is gone after."""
    context = Context()
    rclpy.init(context=context)
    try:
        node = client_node('task_manager_look', context)
        try:
            deadline = time.monotonic() + timeout_sec
            # the graph is the middleware's, kept by its own threads: nothing to spin
            while node.count_publishers(ACTIVE_TASKS_TOPIC) == 0:
                if time.monotonic() >= deadline:
                    return False
                threading.Event().wait(0.1)
            return True
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


class HearingWatch:
    """The check on a client's connection, started by its first listener."""

    def __init__(
        self,
        connection: Connection,
        check: HearingCheck | None = None,
        lost: LostNodeCheck | None = None,
        look: Callable[[], bool] = node_seen_anew,
        serving: Callable[[], bool] = lambda: True,
    ) -> None:
        """`look`: whether a new participant sees the node (a test may give its own);
        `serving`: whether the node's ExecuteTask server (and each of its services the client
        uses) has met the client. The node is reached (for the lost check) when its active list
        reaches the client and it serves: a newcomer's participant can meet the one and never
        the other."""
        self._connection = connection
        self._check = check or HearingCheck()
        self._lost = lost or LostNodeCheck()
        self._look = look
        self._serving = serving
        self._seen: queue.SimpleQueue[bool] = queue.SimpleQueue()
        """What each look found, for the executor thread to take (put by the look's thread)."""
        self._log = NodeLog.of(connection.node)
        self.unheard = Listeners[float](connection.lock)
        """Who is told that the node was not heard again (see `add`)."""
        self._timer: Timer | None = None
        self._client: Client[Any, Any] | None = None
        self._asked: list[Future[Any]] = []

    def add(self, callback: Callable[[float], None]) -> Callable[[], None]:
        """Tell `callback(seconds)` each time the node is not heard again after a hold-up (of
        that long), or is seen anew but not by the client (lost that long); starts the checks
        (once). Returns the unsubscribe."""
        remove = self.unheard.add(Callback(callback, self._log))
        with self._connection.lock:
            start = self._timer is None
            if start:
                node = self._connection.node
                self._client = node.create_client(GetTaskStates, GET_TASK_STATES_SERVICE)
                # the first turn, here: a hold-up before the timer's first is seen too
                reaching = self._connection.matched()
                self._check.turn(time.monotonic(), reaching)
                self._lost.reaching_changed(self._node_reach(reaching))
                self._connection.reaching.add(self)
                self._timer = node.create_timer(self._check.period_sec, self._turn)
        return remove

    def put(self, reaching: frozenset[str]) -> None:
        """What reaches the client changed (the connection's `reaching`, on the executor)."""
        self._check.reaching_changed(time.monotonic(), reaching)
        self._lost.reaching_changed(self._node_reach(reaching))

    def _node_reach(self, reaching: frozenset[str]) -> frozenset[str]:
        """What reaches the client, the active list left out while the node does not serve
        it (its ExecuteTask server not met)."""
        return reaching if self._serving() else reaching - {ACTIVE_TASKS_TOPIC}

    def _turn(self) -> None:
        now, reaching = time.monotonic(), self._connection.matched()
        self._turn_lost(now, reaching)
        step = self._check.turn(now, reaching)
        if step is Step.ASK:
            self._ask()
        elif step is Step.HEARD:
            self._forget_asked()
            self._log.info(
                f'held up {self._check.held_up_for:.1f} s; the Task Manager is heard again'
            )
        elif step is Step.UNHEARD:
            self._forget_asked()
            held_up = self._check.held_up_for
            self._log.error(
                f'held up {held_up:.1f} s, this process has not heard the Task Manager again '
                f'within {self._check.answer_sec:g} s (DDS can stay one-sided after a hold-up '
                'longer than the lease): a new process is needed'
            )
            self.unheard.put(held_up)

    def _turn_lost(self, now: float, reaching: frozenset[str]) -> None:
        while not self._seen.empty():
            self._lost.looked(now, self._seen.get())
        step = self._lost.turn(now, self._node_reach(reaching))
        if step is Step.LOOK:
            threading.Thread(target=self._look_anew, name='task-manager-look', daemon=True).start()
        elif step is Step.UNHEARD:
            lost_for = self._lost.lost_for(now)
            self._log.error(
                f'the Task Manager has not reached this process for {lost_for:.0f} s (its '
                'active list, its ExecuteTask server or a service of it this process uses), '
                'though a new participant of it sees '
                'the node (DDS can stay one-sided after a participant was held up past the '
                'lease, and a newcomer can miss some of the node for good): a new process is '
                'needed'
            )
            self.unheard.put(lost_for)

    def _look_anew(self) -> None:
        try:
            seen = self._look()
        except Exception as error:  # a look that fails counts as one that saw nothing
            self._log.warning(f'could not look for the Task Manager anew: {error}')
            seen = False
        self._seen.put(seen)

    def _ask(self) -> None:
        assert self._client is not None
        asked = self._client.call_async(GetTaskStates.Request())
        asked.add_done_callback(lambda _: self._check.answered())
        self._asked.append(asked)

    def _forget_asked(self) -> None:
        assert self._client is not None
        for asked in self._asked:
            self._client.remove_pending_request(asked)
        self._asked.clear()
