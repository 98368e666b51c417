"""When /task_manager/active_tasks goes out: once per executor turn, and for a large list at
most LARGE_LIST_RATE_HZ times a second.

Every list holds every started task (IN_PROGRESS or PAUSED) and every QUEUED one. A task that
ends is shown once more with its final status, then left out, as the original does: those two
lists go out together. The changes of one executor turn share one publication; with more than
LARGE_LIST entries the changes of up to 1 / LARGE_LIST_RATE_HZ seconds do, so that the cost of
a change does not grow with the number of tasks. Each change still goes out on its own on
/task_manager/task_events.
"""

from collections.abc import Callable
from typing import Protocol

from rclpy.node import Node

from task_manager.core.task import TaskRecord
from task_manager.ros.recording.turn_publication import TurnPublication

LARGE_LIST = 100
"""Entries above which the list's publication rate is bounded."""
LARGE_LIST_RATE_HZ = 10.0


class ActiveTasksSink(Protocol):
    """Where the lists go (the node's publisher)."""

    def publish_active(self, records: list[TaskRecord]) -> None: ...


class ActiveTasksPublication:
    """Gathers changes and publishes active_tasks within the bounds above."""

    def __init__(
        self,
        node: Node,
        listed: Callable[[], list[TaskRecord]],
        sink: ActiveTasksSink,
    ) -> None:
        """`listed`: the tasks the list shows now (queued, running or paused)."""
        self._listed = listed
        self._sink = sink
        self._ended_unpublished: list[TaskRecord] = []
        self._publication = TurnPublication(node, self._publish, self._is_large, LARGE_LIST_RATE_HZ)

    def ended(self, record: TaskRecord) -> None:
        """A started task ended: shown once with its final status, then left out."""
        self._ended_unpublished.append(record)
        self.changed()

    def changed(self) -> None:
        """The list changed: publish it once this executor turn is done (or later, if large)."""
        self._publication.changed()

    def _is_large(self) -> bool:
        return len(self._listed()) + len(self._ended_unpublished) > LARGE_LIST

    def _publish(self) -> None:
        started = self._listed()
        if self._ended_unpublished:
            self._sink.publish_active(started + self._ended_unpublished)
            self._ended_unpublished = []
        self._sink.publish_active(started)
