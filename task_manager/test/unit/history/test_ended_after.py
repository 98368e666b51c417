"""The client's `ended_after`: the history after a sequence, oldest first, a page at a time as
the caller takes them; without ROS (a stand-in answers the history service as the node does:
after the sequence asked, by sequence, at most the limit)."""

from typing import Any

from task_manager_msgs.msg import TaskState as TaskStateMessage
from task_manager_msgs.srv import QueryTaskHistory

from task_manager.client.history import HistoryQueries


class KeptHistory(HistoryQueries):
    """A history of `count` ended tasks numbered from 1; the requests it was asked."""

    def __init__(self, count: int) -> None:
        self.kept = [
            TaskStateMessage(task_id=f't{n}', task_status='DONE', sequence=n)
            for n in range(1, count + 1)
        ]
        self.asked: list[tuple[int, int]] = []

    def _call(self, service_type: Any, name: str, request: Any, timeout_sec: Any = None) -> Any:
        assert service_type is QueryTaskHistory and request.oldest_first
        self.asked.append((request.after_sequence, request.limit))
        after = [m for m in self.kept if m.sequence > request.after_sequence]
        return QueryTaskHistory.Response(tasks=after[: request.limit])


def test_every_task_after_the_sequence_comes_once_in_order_a_page_at_a_time() -> None:
    history = KeptHistory(25)

    taken = [state.sequence for state in history.ended_after(3, page=10)]

    assert taken == list(range(4, 26))
    assert history.asked == [(3, 10), (13, 10), (23, 10)]


def test_pages_are_read_only_as_the_caller_goes_on() -> None:
    history = KeptHistory(25)
    ended = history.ended_after(page=10)

    first = [next(ended).sequence for _ in range(10)]

    assert first == list(range(1, 11)) and history.asked == [(0, 10)]


def test_a_full_last_page_costs_one_empty_read_more() -> None:
    history = KeptHistory(20)

    assert len(list(history.ended_after(page=10))) == 20
    assert history.asked == [(0, 10), (10, 10), (20, 10)]
