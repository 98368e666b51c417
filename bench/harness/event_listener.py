"""A subscriber of /task_manager/task_events in a process of its own, as a dashboard would be.

It counts the events it receives by kind (reading only the kind from each message's bytes).
`/bench/event_counts` (test_msgs/srv/BasicTypes) answers once at least `uint32_value`
ENDED events have been counted, or after COUNT_TIMEOUT_SEC, with the counts as JSON in
`string_value`, and starts counting again from zero.

Kept out of the bench's own process so that the bench's executor, which times the round
trips, does not also serve a message per event: what is measured is the node's cost.
"""

import json
from collections import Counter
from typing import Any

from rclpy.node import Node
from rclpy.task import Future
from test_msgs.srv import BasicTypes

from bench.harness.client import event_and_task_id
from bench.harness.processes import spin_child
from task_manager.core.names import TASK_EVENTS_TOPIC
from task_manager.rclpy_tools import qos
from task_manager_msgs.msg import TaskEvent

LISTENER_NODE_NAME = 'task_manager_bench_event_listener'
EVENT_COUNTS_SERVICE = '/bench/event_counts'
COUNT_TIMEOUT_SEC = 15.0


def _complete(future: Future[Any]) -> None:
    if not future.done():
        future.set_result(None)


class EventListener:
    def __init__(self, node: Node) -> None:
        self._node = node
        # key: event kind, value: how many since the last answer
        self._counts: Counter[str] = Counter()
        self._waiting: tuple[int, Future[Any]] | None = None
        node.create_subscription(
            TaskEvent, TASK_EVENTS_TOPIC, self._on_event, qos.TASK_EVENTS, raw=True
        )
        node.create_service(
            BasicTypes, EVENT_COUNTS_SERVICE, self._answer, qos_profile=qos.DEEP_RELIABLE
        )

    def _on_event(self, data: bytes) -> None:
        kind, _ = event_and_task_id(data)
        self._counts[kind] += 1
        self._wake_if_reached()

    def _wake_if_reached(self) -> None:
        if self._waiting is not None:
            ended, reached = self._waiting
            if self._counts['ENDED'] >= ended:
                _complete(reached)

    async def _answer(self, request: Any, response: Any) -> Any:
        reached: Future[Any] = Future()
        self._waiting = (request.uint32_value, reached)
        timer = self._node.create_timer(COUNT_TIMEOUT_SEC, lambda: _complete(reached))
        self._wake_if_reached()
        await reached
        self._node.destroy_timer(timer)
        self._waiting = None
        response.string_value = json.dumps(dict(self._counts))
        self._counts.clear()
        return response


def main() -> None:
    spin_child(LISTENER_NODE_NAME, EventListener)


if __name__ == '__main__':
    main()
