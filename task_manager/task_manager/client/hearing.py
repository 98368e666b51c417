"""Whether the client still hears the Task Manager after its process was held up.

A process stopped or starved for longer than the DDS lease (5 s, fastdds_discovery.xml) is
forgotten by the node's participant, or forgets it, and the two discover each other again when
it runs on. Measured with the VDA 5050 adapter stopped 9-11 s while the node published
thousands of event batches: in 4 of 5 stops that rediscovery stayed one-sided for good. The
node took the adapter's requests and ran them, and nothing of the node reached the adapter
again (no reply, no event, not even to a reader made afterwards), with shared memory or UDP
alone; with a 60 s lease on every participant it always heard the node again. The cause is
inside Fast DDS; a new participant (a new process) is heard at once.

So a process that must keep hearing the node (a gateway, a follow of taskctl) asks for the
check (`on_node_unheard`): a timer on the client's executor notices a turn late by
HELD_UP_SEC or more; the client then asks the node a question that any node answers at once
(GetTaskStates of no task, sent again while unanswered) and waits for the answer and for every
topic that reached the client before the hold-up to reach it again. Neither within ANSWER_SEC:
the listeners are told how long the process was held up, and it is theirs to start a new
participant (the gateways exit, for their supervisor to start them again).
"""

import time
from collections.abc import Callable, Set
from enum import Enum
from typing import Any

from rclpy.client import Client
from rclpy.task import Future
from rclpy.timer import Timer
from task_manager_msgs.srv import GetTaskStates

from task_manager.client.connection import SERVICE_RETRY_SEC, Connection
from task_manager.client.listeners import Callback, Listeners
from task_manager.core.names import GET_TASK_STATES_SERVICE
from task_manager.rclpy_tools.log import NodeLog

CHECK_PERIOD_SEC = 1.0
"""How often the check's timer runs (only in a client asked for the check)."""
HELD_UP_SEC = 4.0
"""A turn of the timer this late: the process was held up. A hold-up of s seconds makes a turn
late by s - 1 to s: one that outlasts the 5 s lease is always seen."""
ANSWER_SEC = 10.0
"""How long after a hold-up the Task Manager has to be heard again: the lease, then a second
for the participants' announcements, with room for a node busy with a flood."""


class Step(Enum):
    """What a turn of the check asks of its client."""

    NOTHING = 'nothing'
    ASK = 'ask the Task Manager'
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


class HearingWatch:
    """The check on a client's connection, started by its first listener."""

    def __init__(self, connection: Connection, check: HearingCheck | None = None) -> None:
        self._connection = connection
        self._check = check or HearingCheck()
        self._log = NodeLog.of(connection.node)
        self.unheard = Listeners[float](connection.lock)
        """Who is told, with how long the process was held up, that the node was not heard
        again after it."""
        self._timer: Timer | None = None
        self._client: Client[Any, Any] | None = None
        self._asked: list[Future[Any]] = []

    def add(self, callback: Callable[[float], None]) -> Callable[[], None]:
        """Tell `callback(held_up_sec)` each time the node is not heard again after a hold-up;
        starts the check (once). Returns the unsubscribe."""
        remove = self.unheard.add(Callback(callback, self._log))
        with self._connection.lock:
            start = self._timer is None
            if start:
                node = self._connection.node
                self._client = node.create_client(GetTaskStates, GET_TASK_STATES_SERVICE)
                # the first turn, here: a hold-up before the timer's first is seen too
                self._check.turn(time.monotonic(), self._connection.matched())
                self._connection.reaching.add(self)
                self._timer = node.create_timer(self._check.period_sec, self._turn)
        return remove

    def put(self, reaching: frozenset[str]) -> None:
        """What reaches the client changed (the connection's `reaching`, on the executor)."""
        self._check.reaching_changed(time.monotonic(), reaching)

    def _turn(self) -> None:
        step = self._check.turn(time.monotonic(), self._connection.matched())
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
