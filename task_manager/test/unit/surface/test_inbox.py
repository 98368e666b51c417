"""An iterator's inbox of the Python client (client/listeners.py): bounded, it drops what comes
past its unread bound and its reader is told where, never silently; the end of the updates is
always kept."""

import math

import pytest

from task_manager.client.handle import TaskHandle
from task_manager.client.listeners import End, Inbox, drain
from task_manager.core.bounds import UPDATES_UNREAD_MAX
from task_manager.core.errors import FellBehind

NO_WAIT_SEC = 0.0


def test_updates_within_the_bound_are_read_in_order() -> None:
    inbox: Inbox[int] = Inbox()
    for number in range(5):
        inbox.put(number)

    assert list(drain(inbox, NO_WAIT_SEC, None)) == [0, 1, 2, 3, 4]
    assert inbox.max_unread == UPDATES_UNREAD_MAX


def test_past_the_bound_the_reader_gets_what_was_kept_then_fell_behind_with_the_count() -> None:
    inbox: Inbox[int] = Inbox(max_unread=3)
    for number in range(7):
        inbox.put(number)
    read: list[int] = []

    dropped = r'kept 3 updates unread and dropped the next \(4 so far\)'
    with pytest.raises(FellBehind, match=dropped):
        for number in drain(inbox, NO_WAIT_SEC, None):
            read.append(number)

    assert read == [0, 1, 2]


def test_the_end_of_the_updates_is_kept_when_the_inbox_is_full() -> None:
    inbox: Inbox[int] = Inbox(max_unread=2)
    inbox.put(0)
    inbox.put(1)
    inbox.put(End.OF_UPDATES)

    assert list(drain(inbox, None, None)) == [0, 1]  # ended, not waiting for good


@pytest.mark.parametrize('timeout_sec', [math.inf, math.nan, -1.0])
def test_a_wait_the_client_cannot_keep_is_refused_before_it_waits(timeout_sec: float) -> None:
    """An infinite timeout reached the queue's wait as OverflowError; None waits for good."""
    inbox: Inbox[int] = Inbox()
    with pytest.raises(ValueError, match='timeout_sec must be'):
        next(drain(inbox, timeout_sec, None))
    with pytest.raises(ValueError, match='timeout_sec must be'):
        TaskHandle(owner=None, task_id='t', task_name='n').result(timeout_sec)  # type: ignore[arg-type]
