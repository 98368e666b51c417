"""taskctl's way to the Task Manager without a node: a client that has not met it within half
the timeout gives way to a new participant for the other half (cli.common.reach). The clients
here are stand-ins that meet the node or not; the real participants are the integration
tests' (every taskctl test goes through reach)."""

import threading
from collections.abc import Callable, Collection

import pytest

from task_manager import TaskManagerUnavailable
from task_manager.cli.common import reach


class StandIn:
    """A client that meets the Task Manager or never does; what was asked of it."""

    def __init__(self, timeout_sec: float, meets: bool, meets_late: bool = False) -> None:
        """`meets_late`: not within its first wait, at any later one (a slow participant)."""
        self.timeout_sec = timeout_sec
        self.meets = meets
        self.meets_late = meets_late
        self.waits: list[tuple[float, bool, tuple[str, ...]]] = []
        self.closed = 0

    def wait_until_available(
        self,
        timeout_sec: float | None = None,
        *,
        events: bool = False,
        services: Collection[str] = (),
    ) -> None:
        assert timeout_sec is not None
        self.waits.append((timeout_sec, events, tuple(services)))
        if not (self.meets or (self.meets_late and len(self.waits) > 1)):
            raise TaskManagerUnavailable(f'no Task Manager answered within {timeout_sec:g} s')

    def close(self) -> None:
        self.closed += 1


def _new_clients(
    *meets: bool,
) -> tuple[list[StandIn], Callable[[float], tuple[StandIn, threading.Event]]]:
    made: list[StandIn] = []
    meeting = iter(meets)

    def new_client(timeout_sec: float) -> tuple[StandIn, threading.Event]:
        made.append(StandIn(timeout_sec, next(meeting)))
        return made[-1], threading.Event()

    return made, new_client


def test_a_client_that_meets_the_node_is_kept_and_no_other_is_made() -> None:
    first, unheard = StandIn(10.0, meets=True), threading.Event()
    made, new_client = _new_clients()
    kept = reach(first, unheard, new_client, events=True)
    assert kept == (first, unheard)
    assert first.waits == [(5.0, True, ())] and first.closed == 0 and made == []


def test_a_client_that_does_not_gives_way_to_a_new_one_for_the_other_half() -> None:
    """Not met: the node's action server, a topic or a service the verb calls."""
    first = StandIn(10.0, meets=False)
    made, new_client = _new_clients(True)
    client, _ = reach(
        first, threading.Event(), new_client, False, ['/task_manager/get_task_states']
    )
    assert client is made[0] and client.timeout_sec == 10.0
    assert first.waits == [(5.0, False, ('/task_manager/get_task_states',))] and first.closed == 1
    assert client.waits == first.waits and client.closed == 0


def test_when_neither_meets_it_both_are_closed_and_the_error_says_so() -> None:
    first = StandIn(5.0, meets=False)
    made, new_client = _new_clients(False)
    with pytest.raises(TaskManagerUnavailable) as raised:
        reach(first, threading.Event(), new_client, events=False)
    assert str(raised.value) == (
        'no Task Manager answered within 2.5 s (and 2.5 s before with another DDS participant)'
    )
    assert first.closed == 1 and made[0].closed == 1


def test_a_first_client_that_met_the_node_meanwhile_is_kept_if_the_new_one_did_not() -> None:
    """A loaded machine: the first participant slower than half the timeout, not unlucky."""
    first = StandIn(10.0, meets=False, meets_late=True)
    made, new_client = _new_clients(False)
    unheard = threading.Event()

    kept = reach(first, unheard, new_client, events=True)

    assert kept == (first, unheard) and first.closed == 0 and made[0].closed == 1
    assert first.waits == [(5.0, True, ()), (0.0, True, ())]
