"""Noticing that the server behind running tasks is gone.

While a runner has tasks in flight, its server is checked every `check_period_sec` (on the
node's timer of timeouts, rclpy_tools.timeouts):
an action server must answer a harmless probe (a cancel request for a goal id that does
not exist; one each check, so that an answer lost does not stop the probing), or give
another sign of life (a goal's response, feedback, a result); a service must still be on
the ROS graph. A server that has given no sign of life for `loss_timeout_sec` is lost, and
its tasks end ERROR. A killed service process
leaves the graph only when its DDS lease expires, so for services the bound counts from
that moment, the moment the loss becomes visible.

A check calls only the tasks that asked for it (an action asks again for a result after 1, 2,
4, ... checks), not each of the tasks in flight: a thousand goals held for minutes cost the
node no work per goal each second.
"""

from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import Any, Protocol

from rclpy.node import Node
from rclpy.task import Future

from task_manager.rclpy_tools.log import NodeLog
from task_manager.rclpy_tools.timeouts import timeouts_of

# A probe answers True (alive now), False (gone now), or a future that completes if alive.
Probe = Callable[[], bool | Future[Any]]


class FailableExecution(Protocol):
    """A running task that can be ended ERROR without its server."""

    outcome: Future[Any]

    def fail(self, reason: str) -> None: ...

    def on_watch_tick(self, tick: int) -> int | None:
        """Called at the check numbered `tick` of its server (an action asks for its result
        again if none came); the check at which it wants the next call, None for none (it is
        called at every check anyway while the watch's `on_tick` says so)."""


@dataclass(frozen=True)
class WatchSettings:
    """How often servers are checked and how long silence may last before they are lost."""

    check_period_sec: float = 1.0
    loss_timeout_sec: float = 5.0


class ServerWatch:
    """Watches one server while tasks run on it; once it is lost, they end ERROR."""

    def __init__(
        self,
        node: Node,
        probe: Probe,
        settings: WatchSettings,
        loss: str,
        on_tick: Callable[[], bool] | None = None,
    ) -> None:
        """`loss` says what happened, e.g. 'service /x left the ROS graph'; `on_tick` is
        called at each check, before the running tasks' on_watch_tick, and says whether every
        one of them is to be called at this check (say, its server's DDS ids changed)."""
        self._node = node
        self._probe = probe
        self._on_tick = on_tick
        self._settings = settings
        self._loss = loss
        self._in_flight: set[FailableExecution] = set()
        self._timeouts = timeouts_of(node)
        self._next_check: Hashable | None = None  # its key in the node's timeouts
        self._last_alive_ns = 0
        self._tick = 0  # the checks made so far
        # key: a task in flight, value: the check at which it is called next
        self._due_at: dict[FailableExecution, int] = {}
        # key: a check, value: the tasks due then (and some since called earlier: see _due_at)
        self._due: dict[int, list[FailableExecution]] = {}

    def _now_ns(self) -> int:
        return self._node.get_clock().now().nanoseconds

    @property
    def watching(self) -> bool:
        """Whether tasks run on the server (its checks are on)."""
        return self._next_check is not None

    def track(self, execution: FailableExecution) -> None:
        """Watch the server while `execution` runs."""
        self._in_flight.add(execution)
        if self._next_check is None:
            self._last_alive_ns = self._now_ns()
            self._check_later()
        self._call_at(execution, self._tick + 1)
        execution.outcome.add_done_callback(lambda _: self._untrack(execution))

    def _call_at(self, execution: FailableExecution, tick: int | None) -> None:
        if tick is None or execution not in self._in_flight:
            self._due_at.pop(execution, None)
            return
        if self._due_at.get(execution) != tick:
            self._due_at[execution] = tick
            self._due.setdefault(tick, []).append(execution)

    def _check_later(self) -> None:
        self._next_check = self._timeouts.after(self._settings.check_period_sec, self._check)

    def _untrack(self, execution: FailableExecution) -> None:
        self._in_flight.discard(execution)
        self._due_at.pop(execution, None)
        if not self._in_flight and self._next_check is not None:
            self._timeouts.cancel(self._next_check)
            self._next_check = None
            self._due.clear()

    def mark_alive(self) -> None:
        """The server gave a sign of life (a probe's answer, a goal's response, feedback, a
        result): under a burst a probe's answer waits its turn behind the rest."""
        self._last_alive_ns = self._now_ns()

    def _check(self) -> None:
        self._check_later()  # the next check first: one that raises must not end the watch
        self._send_probe()  # each tick: an answer lost must not leave the server unprobed
        self._tick += 1
        every_one = self._on_tick() if self._on_tick is not None else False
        due = self._due.pop(self._tick, [])
        if every_one:
            due = list(self._in_flight)
        for execution in due:
            if every_one or self._due_at.get(execution) == self._tick:
                self._call_at(execution, execution.on_watch_tick(self._tick))
        silent_sec = (self._now_ns() - self._last_alive_ns) / 1e9
        if silent_sec > self._settings.loss_timeout_sec and self._in_flight:
            NodeLog.of(self._node).error(
                f'{self._loss}; failing its {len(self._in_flight)} task(s)'
            )
            for execution in list(self._in_flight):
                execution.fail(self._loss)

    def _send_probe(self) -> None:
        answer = self._probe()
        if isinstance(answer, bool):
            if answer:
                self.mark_alive()
            return
        answer.add_done_callback(lambda done: None if done.cancelled() else self.mark_alive())
