"""The event stream's cost: dispatch latency and burst throughput with it on vs off.

See node_settings.py for how the two are compared. Throughout, a subscriber in a process of
its own (event_listener.py) follows /task_manager/task_events, as a dashboard on the robot
would: with the stream on, every measured task must bring its RECEIVED, STARTED and ENDED
events; with it off, none may come.
"""

import json
from collections import Counter
from typing import Any

from test_msgs.srv import BasicTypes

from bench.harness import config
from bench.harness.context import BenchContext
from bench.harness.event_listener import EVENT_COUNTS_SERVICE
from bench.harness.processes import start_event_listener
from bench.harness.replies import BenchError, wait_reply
from bench.node.node_settings import Setting, compare
from task_manager.rclpy_tools import qos

TASK_EVENTS = ('RECEIVED', 'STARTED', 'ENDED')
COUNTS_TIMEOUT_SEC = 30.0
EVENTS_OFF = Setting('events off', {'publish_task_events': False})
EVENTS_ON = Setting('events on', {'publish_task_events': True})


class EventCounts:
    """The events the listener received for the tasks measured with the stream on."""

    def __init__(self, ctx: BenchContext) -> None:
        self._ctx = ctx
        self._service: Any = ctx.client.harness.node.create_client(
            BasicTypes, EVENT_COUNTS_SERVICE, qos_profile=qos.DEEP_RELIABLE
        )
        if not self._service.wait_for_service(timeout_sec=config.CONNECT_TIMEOUT_SEC):
            raise BenchError(f'{EVENT_COUNTS_SERVICE} not available')
        self.tasks = 0
        # key: event kind, value: how many
        self.events: Counter[str] = Counter()

    def take(self, ended: int = 0) -> Counter[str]:
        """The listener's counts once it has `ended` ENDED events (bounded); it starts over."""
        request = BasicTypes.Request(uint32_value=ended)
        reply = wait_reply(self._ctx.client.call(self._service, request), 'event counts',
                           COUNTS_TIMEOUT_SEC)  # fmt: skip
        return Counter(json.loads(reply.response.string_value))

    def after_phase(self, setting: Setting, tasks: int) -> None:
        """All of the phase's events if on, none if off."""
        seen = self.take(tasks if setting is EVENTS_ON else 0)
        if setting is EVENTS_OFF:
            if seen:
                raise BenchError(f'task events with publish_task_events false: {dict(seen)}')
            return
        self.tasks += tasks
        self.events.update(seen)

    def destroy(self) -> None:
        self._ctx.client.harness.node.destroy_client(self._service)

    def note(self) -> str:
        counts = ', '.join(f'{kind} {self.events[kind]}' for kind in TASK_EVENTS)
        others = ', '.join(f'{k} {n}' for k, n in self.events.items() if k not in TASK_EVENTS)
        return (
            f'events on vs off: a subscriber in its own process received, for the {self.tasks} '
            f'tasks measured with the stream on: {counts}'
            + (f', {others}' if others else '')
            + '; off: none'
        )


def run(ctx: BenchContext) -> None:
    listener = start_event_listener(ctx.log_dir)
    try:
        counts = EventCounts(ctx)
        try:
            compare(ctx, EVENTS_OFF, EVENTS_ON, counts.after_phase, on_warmed_up=counts.take)
        finally:
            counts.destroy()
    finally:
        listener.stop()
    ctx.report.note(counts.note())
