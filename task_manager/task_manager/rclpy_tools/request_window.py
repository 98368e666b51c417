"""At most a few requests of one service client unanswered at a time; the rest wait, in order.

A ROS 2 service server keeps only its last few unread requests (10 by default in rclpy and
rclcpp, the depth of its request reader; Nav2's servers too) and drops older ones unanswered
when a burst reaches it faster than its executor takes them: 200 cancels sent at once by a
`system/stop` reached a server as 19. Sending at most `size` (fewer than 10) at a time, and the
next as each is answered, keeps any burst within what a server keeps.

A request unanswered when one sent after it is answered gives its place up: the server takes
requests in order, so it has taken this one (and holds it, as a goal callback may) or dropped
it; either way it is in no queue of the server any more. A server that answers nothing is busy
(or gone): its places are kept, however long, since a request sent then is one more in its
queue, and past 10 the server drops the oldest. Only when none of them has been answered
within `slot_timeout_sec` (they were lost, say with a server that restarted) are they given
up, so that a lost answer never closes the window for good. An answer that comes after its
place was given up still completes its future.

Runs on the node's executor thread (its callbacks and timer), as the node's runners do.
"""

import functools
import sys
import time
from collections import OrderedDict, deque
from itertools import count
from typing import Any, NamedTuple

from rclpy.client import Client
from rclpy.node import Node
from rclpy.task import Future
from rclpy.timer import Timer

from task_manager.rclpy_tools.calls import call_async, forget
from task_manager.rclpy_tools.futures import completed_future

# Below the 10 unread requests rclpy's and rclcpp's servers keep by default.
DEFAULT_SIZE = 8
# A server that has answered none of the requests holding places for this long lost them.
DEFAULT_SLOT_TIMEOUT_SEC = 5.0


class _Sent(NamedTuple):
    """A request sent: the client's future of it and its place in the order of sending."""

    future: Future[Any]
    number: int


class RequestWindow:
    """Sends the requests of one service client, at most `size` unanswered at a time (0: no
    bound, each sent at once)."""

    def __init__(
        self,
        node: Node,
        client: Client[Any, Any],
        size: int = DEFAULT_SIZE,
        slot_timeout_sec: float = DEFAULT_SLOT_TIMEOUT_SEC,
    ) -> None:
        self._node = node
        self._client = client
        self._size = size or sys.maxsize
        self._slot_timeout_sec = slot_timeout_sec
        self._waiting: deque[tuple[Any, Future[Any]]] = deque()
        # the caller's futures of the requests in `_waiting` not forgotten
        self._unsent: set[Future[Any]] = set()
        # key: the caller's future of a request holding a place, value: its number and when it
        # was sent; in the order of sending
        self._in_flight: OrderedDict[Future[Any], tuple[int, float]] = OrderedDict()
        # key: the caller's future, value: the request sent, not answered nor forgotten yet
        self._sent: dict[Future[Any], _Sent] = {}
        self._numbers = count()
        # key: the caller's future of a request waiting its turn, value: done when it is sent
        self._sending: dict[Future[Any], Future[None]] = {}
        self._timer: Timer | None = None

    def call_async(self, request: Any) -> Future[Any]:
        """A future of the response, as Client.call_async's; the request waits its turn."""
        future: Future[Any] = Future()
        self._waiting.append((request, future))
        self._unsent.add(future)
        self._pump()
        return future

    def holds(self, future: Future[Any]) -> bool:
        """Whether this future is of a request of this window (sent or waiting its turn)."""
        return future in self._sent or future in self._unsent

    def sent(self, future: Future[Any]) -> Future[None]:
        """A future done once this request has left the window (at once if it has; cancelled
        if it is forgotten first): the time it waited its turn is the node's, not the
        server's."""
        if future not in self._unsent:
            return completed_future()
        return self._sending.setdefault(future, Future())

    def waits(self, future: Future[Any]) -> bool:
        """Whether this future's request still waits its turn, not sent yet."""
        return future in self._unsent

    def forget(self, future: Future[Any]) -> None:
        """The caller waits no more for this request's response (sent or not)."""
        self._unsent.discard(future)
        signal = self._sending.pop(future, None)
        if signal is not None:
            signal.cancel()
        sent = self._sent.pop(future, None)
        if sent is not None and not sent.future.done():
            forget(self._client, sent.future)
        if not future.done():
            future.cancel()
        self._in_flight.pop(future, None)
        self._pump()

    def _pump(self) -> None:
        now = time.monotonic()
        while self._in_flight:  # oldest first: a server silent that long lost them
            oldest, (_, sent_at) = next(iter(self._in_flight.items()))
            if now - sent_at < self._slot_timeout_sec:
                break
            del self._in_flight[oldest]
        while self._waiting and len(self._in_flight) < self._size:
            request, future = self._waiting.popleft()
            if future.done():  # forgotten while it waited
                continue
            self._unsent.discard(future)
            number = next(self._numbers)
            sent = call_async(self._client, request)
            self._sent[future] = _Sent(sent, number)
            self._in_flight[future] = (number, now)
            sent.add_done_callback(functools.partial(self._answered, future))
            signal = self._sending.pop(future, None)
            if signal is not None:
                signal.set_result(None)
        self._arm(bool(self._waiting))

    def _answered(self, future: Future[Any], answer: Future[Any]) -> None:
        sent = self._sent.pop(future, None)
        self._in_flight.pop(future, None)
        if sent is not None and not answer.cancelled():
            # the server has taken every request sent before this one
            while self._in_flight and next(iter(self._in_flight.values()))[0] < sent.number:
                self._in_flight.popitem(last=False)
            if not future.done():
                future.set_result(answer.result())
        self._pump()

    def _arm(self, waiting: bool) -> None:
        """While requests wait for a place, a timer gives up the places of unanswered ones."""
        if not waiting:
            if self._timer is not None:
                self._timer.cancel()
            return
        if self._timer is None:
            self._timer = self._node.create_timer(self._slot_timeout_sec, self._pump)
        elif self._timer.is_canceled():
            self._timer.reset()

    def destroy(self) -> None:
        if self._timer is not None:
            self._node.destroy_timer(self._timer)
            self._timer = None
