"""The client's hearing checks: after its process was held up, it asks the node and waits to
hear it again, or tells its listeners it did not; a node lost for a while is looked for by a
new participant, and one that sees it while the client does not means the client is deaf.
Their decisions without ROS, then the checks on a real connection to a real node (stopped
for the cases where nothing comes back)."""

import os
import queue
import signal
import threading
import time
from collections.abc import Iterator

import pytest
from task_manager_msgs.msg import ActiveTaskArray
from task_manager_msgs.srv import GetTaskStates

from task_manager.client import TaskManagerClient
from task_manager.client.connection import SERVICE_RETRY_SEC, Connection
from task_manager.client.hearing import (
    HearingCheck,
    HearingWatch,
    LostNodeCheck,
    Step,
    node_seen_anew,
)
from task_manager.core.names import ACTIVE_TASKS_TOPIC, TASK_EVENT_BATCHES_TOPIC
from task_manager.rclpy_tools import qos
from task_manager.testing.gateway import wait_until
from task_manager.testing.process import LaunchTaskManager, NodeProcess, service_task

TIMEOUT_SEC = 15.0
# the check on a real connection, quicker than the client's (the node stopped in all less than
# its 5 s lease, so that the test's other participants keep it)
HELD_UP_SEC = 1.0
ANSWER_SEC = 1.5
PERIOD_SEC = 0.2
TOPICS = frozenset({ACTIVE_TASKS_TOPIC, TASK_EVENT_BATCHES_TOPIC})


def _held_up(check: HearingCheck, reaching: frozenset[str] = TOPICS) -> float:
    """Turns on time while `reaching` reaches the client, then one 5 s late; its time."""
    assert check.turn(0.0, reaching) is Step.NOTHING
    assert check.turn(1.0, reaching) is Step.NOTHING
    assert check.turn(7.0, frozenset()) is Step.ASK
    return 7.0


def test_turns_on_time_ask_nothing() -> None:
    check = HearingCheck()
    assert [check.turn(float(second), TOPICS) for second in range(10)] == [Step.NOTHING] * 10
    assert not check.checking and check.expecting == TOPICS


def test_after_a_hold_up_the_node_is_heard_once_it_answered_and_every_topic_is_back() -> None:
    check = HearingCheck()
    now = _held_up(check)
    assert check.held_up_for == 5.0
    check.answered()
    assert check.turn(now + 1, frozenset({ACTIVE_TASKS_TOPIC})) is Step.NOTHING
    assert check.turn(now + 2, TOPICS) is Step.HEARD
    assert not check.checking


def test_a_node_that_does_not_answer_is_asked_again_then_unheard() -> None:
    check = HearingCheck(answer_sec=10.0)
    now = _held_up(check)
    steps = {second: check.turn(now + second, TOPICS) for second in range(1, 11)}
    asked_at = [second for second, step in steps.items() if step is Step.ASK]
    assert asked_at == [1, 2, 4, 8]  # SERVICE_RETRY_SEC, then twice as long each time
    assert SERVICE_RETRY_SEC == 0.5
    assert steps[10] is Step.UNHEARD and not check.checking


def test_an_answer_without_the_topics_back_is_unheard() -> None:
    """The node's answer came, but its event stream did not reach the client again."""
    check = HearingCheck(answer_sec=10.0)
    now = _held_up(check)
    check.answered()
    steps = [check.turn(now + second, frozenset({ACTIVE_TASKS_TOPIC})) for second in range(1, 11)]
    assert steps == [Step.NOTHING] * 9 + [Step.UNHEARD]


def test_a_client_that_heard_nothing_before_checks_nothing() -> None:
    check = HearingCheck()
    assert check.turn(0.0, frozenset()) is Step.NOTHING
    assert check.turn(7.0, frozenset()) is Step.NOTHING
    assert not check.checking


def test_topics_that_reached_the_client_between_turns_are_expected_back() -> None:
    """A client that met its node less than a turn before the hold-up checks it too."""
    check = HearingCheck()
    assert check.turn(0.0, frozenset()) is Step.NOTHING
    check.reaching_changed(0.5, TOPICS)
    assert check.turn(7.0, frozenset()) is Step.ASK
    assert check.expecting == TOPICS


def test_topics_lost_in_a_hold_up_before_its_late_turn_are_still_expected_back() -> None:
    """The lease ran out while the process was held up: the readers lose their writers as it
    goes on, before the check's overdue turn."""
    check = HearingCheck()
    assert check.turn(0.0, TOPICS) is Step.NOTHING
    check.reaching_changed(6.9, frozenset())
    assert check.turn(7.0, frozenset()) is Step.ASK
    assert check.expecting == TOPICS


def test_a_hold_up_during_a_check_begins_it_again() -> None:
    """Held up again before the answer could come: the wait for it starts over."""
    check = HearingCheck(answer_sec=10.0)
    now = _held_up(check)
    assert check.turn(now + 21.0, frozenset()) is Step.ASK  # 20 s late
    assert check.held_up_for == 20.0
    assert check.turn(now + 22.0, frozenset()) is Step.ASK  # not answered yet
    check.answered()
    assert check.turn(now + 23.0, TOPICS) is Step.HEARD


def test_an_answer_outside_a_check_counts_for_nothing() -> None:
    check = HearingCheck(answer_sec=10.0)
    check.answered()
    now = _held_up(check)
    assert check.turn(now + 1.0, TOPICS) is Step.ASK  # asked again: not answered


LOST = frozenset({TASK_EVENT_BATCHES_TOPIC})  # the active list no longer reaches the client


def _lost_at_10(check: LostNodeCheck) -> None:
    """The node's active list reached the client at 0, and no longer from 10 s."""
    assert check.turn(0.0, TOPICS) is Step.NOTHING
    assert check.turn(10.0, LOST) is Step.NOTHING


def test_a_client_that_never_met_a_node_looks_for_it_too() -> None:
    """A newcomer whose participant never matches the node's endpoints, as others do."""
    check = LostNodeCheck(lost_sec=10.0, grace_sec=5.0)
    steps = {second: check.turn(float(second), frozenset()) for second in range(20)}
    assert [second for second, step in steps.items() if step is Step.LOOK] == [10]
    check.looked(12.0, seen=True)
    assert check.turn(16.0, frozenset()) is Step.NOTHING
    assert check.turn(17.0, frozenset()) is Step.UNHEARD
    assert check.lost_for(17.0) == 17.0


def test_a_lost_node_is_looked_for_after_lost_sec_then_each_look_again_sec() -> None:
    check = LostNodeCheck(lost_sec=10.0, look_again_sec=30.0)
    _lost_at_10(check)
    steps = {second: check.turn(float(second), LOST) for second in range(11, 80)}
    assert [second for second, step in steps.items() if step is Step.LOOK] == [20]
    check.looked(21.0, seen=False)
    steps = {second: check.turn(float(second), LOST) for second in range(80, 120)}
    assert [second for second, step in steps.items() if step is Step.LOOK] == [80]
    check.looked(81.0, seen=False)
    steps = {second: check.turn(float(second), LOST) for second in range(81, 120)}
    assert [second for second, step in steps.items() if step is Step.LOOK] == [110]


def test_a_node_seen_anew_but_not_by_the_client_after_the_grace_is_unheard() -> None:
    check = LostNodeCheck(lost_sec=10.0, grace_sec=5.0)
    _lost_at_10(check)
    assert check.turn(20.0, LOST) is Step.LOOK
    check.looked(23.0, seen=True)
    assert [check.turn(float(second), LOST) for second in range(24, 29)] == [Step.NOTHING] * 4 + [
        Step.UNHEARD
    ]
    assert check.lost_for(28.0) == 18.0


def test_a_node_seen_anew_that_reaches_the_client_within_the_grace_is_heard() -> None:
    """A node started again, found by the new participant a moment before the client."""
    check = LostNodeCheck(lost_sec=10.0, grace_sec=5.0)
    _lost_at_10(check)
    assert check.turn(20.0, LOST) is Step.LOOK
    check.looked(23.0, seen=True)
    assert check.turn(24.0, TOPICS) is Step.NOTHING
    assert {check.turn(float(second), TOPICS) for second in range(25, 60)} == {Step.NOTHING}
    assert check.lost_for(60.0) == 0.0


@pytest.fixture
def connection() -> Iterator[Connection]:
    connection = Connection('test_hearing', TIMEOUT_SEC)
    yield connection
    connection.close()


def _launch(launch_task_manager: LaunchTaskManager, topic_prefix: str) -> NodeProcess:
    """A node (its one task's server is not needed here); its process."""
    probe = launch_task_manager({'instant': service_task('instant', f'{topic_prefix}/instant')})
    return probe.process  # type: ignore[no-any-return]


def _watched(connection: Connection) -> tuple[HearingCheck, queue.SimpleQueue[float]]:
    """The connection, following the active lists, checked with short times; what it tells."""
    check = HearingCheck(HELD_UP_SEC, ANSWER_SEC, PERIOD_SEC)
    watch = HearingWatch(connection, check)
    connection.subscribe(ActiveTaskArray, ACTIVE_TASKS_TOPIC, qos.ACTIVE_TASKS, lambda _: None)
    connection.start()
    assert connection.wait_matched({ACTIVE_TASKS_TOPIC}, TIMEOUT_SEC)
    told: queue.SimpleQueue[float] = queue.SimpleQueue()
    watch.add(told.put)
    wait_until(lambda: check.expecting == {ACTIVE_TASKS_TOPIC}, 'a first turn of the check')
    return check, told


def _hold_up(connection: Connection, seconds: float) -> None:
    """Keep the connection's executor thread in a callback for `seconds` (the hold-up is
    the test's input): its check's next turn comes that late."""
    holding = threading.Event()

    def hold() -> None:
        timer.cancel()
        holding.set()
        threading.Event().wait(seconds)

    timer = connection.node.create_timer(0.01, hold)
    assert holding.wait(TIMEOUT_SEC), 'the executor never ran the hold-up'


def test_a_client_held_up_hears_its_node_again(
    launch_task_manager: LaunchTaskManager, topic_prefix: str, connection: Connection
) -> None:
    _launch(launch_task_manager, topic_prefix)
    check, told = _watched(connection)

    _hold_up(connection, HELD_UP_SEC + 2 * PERIOD_SEC)

    wait_until(
        lambda: check.held_up_for >= HELD_UP_SEC and not check.checking,
        'the check after the hold-up',
        TIMEOUT_SEC,
    )
    assert told.empty()


def test_a_client_held_up_that_does_not_hear_its_node_again_tells_its_listeners(
    launch_task_manager: LaunchTaskManager, topic_prefix: str, connection: Connection
) -> None:
    """The node stopped (SIGSTOP) from before the hold-up until the check gave up on it."""
    node = _launch(launch_task_manager, topic_prefix)
    check, told = _watched(connection)

    os.kill(node.process.pid, signal.SIGSTOP)
    try:
        _hold_up(connection, HELD_UP_SEC + 2 * PERIOD_SEC)
        held_up = told.get(timeout=TIMEOUT_SEC)
    finally:
        os.kill(node.process.pid, signal.SIGCONT)

    assert held_up >= HELD_UP_SEC
    assert not check.checking


def test_a_new_participant_sees_a_running_node_and_not_a_stopped_one(
    launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    node = _launch(launch_task_manager, topic_prefix)
    assert node_seen_anew(TIMEOUT_SEC)

    assert node.stop() == 0
    assert not node_seen_anew(1.0)


class LostWatch:
    """A connection following the active lists, its lost check with short times and a look
    that always sees the node (as a new participant sees a node the client is deaf to); when
    it looked, and what its listeners are told."""

    def __init__(self, connection: Connection, serving: bool = True) -> None:
        self.looks: list[float] = []
        self.told: queue.SimpleQueue[float] = queue.SimpleQueue()
        lost = LostNodeCheck(lost_sec=0.5, look_again_sec=TIMEOUT_SEC, grace_sec=0.5)
        self._watch = HearingWatch(
            connection,
            HearingCheck(period_sec=PERIOD_SEC),
            lost,
            look=self._look,
            serving=lambda: serving,
        )
        connection.subscribe(ActiveTaskArray, ACTIVE_TASKS_TOPIC, qos.ACTIVE_TASKS, lambda _: None)
        connection.start()

    def _look(self) -> bool:
        self.looks.append(time.monotonic())
        return True

    def start(self) -> float:
        """Start the checks; when."""
        self._watch.add(self.told.put)
        return time.monotonic()


def test_a_client_that_lost_its_node_which_a_new_participant_sees_is_told(
    launch_task_manager: LaunchTaskManager, topic_prefix: str, connection: Connection
) -> None:
    """The node stopped (SIGINT): the client loses it; the look makes the client's listeners
    told once the grace is over."""
    node = _launch(launch_task_manager, topic_prefix)
    watch = LostWatch(connection)
    assert connection.wait_matched({ACTIVE_TASKS_TOPIC}, TIMEOUT_SEC)
    stopped_at = watch.start()

    assert node.stop() == 0

    lost_for = watch.told.get(timeout=TIMEOUT_SEC)
    assert len(watch.looks) == 1 and watch.looks[0] - stopped_at >= 0.5
    assert lost_for >= 1.0  # lost_sec, then the grace


def test_a_client_that_never_met_a_node_which_a_new_participant_sees_is_told(
    connection: Connection,
) -> None:
    """No node in reach of the client (as a newcomer whose participant never matches the
    node's endpoints while others do): told once a look saw one and the grace is over."""
    watch = LostWatch(connection)
    started_at = watch.start()

    lost_for = watch.told.get(timeout=TIMEOUT_SEC)
    assert len(watch.looks) == 1 and watch.looks[0] - started_at >= 0.5
    assert lost_for >= 1.0  # lost_sec, then the grace


def test_a_client_whose_node_never_serves_it_which_a_new_participant_sees_is_told(
    launch_task_manager: LaunchTaskManager, topic_prefix: str, connection: Connection
) -> None:
    """The node's active list reaches the client, its ExecuteTask server never does (here the
    check is told so, as for a newcomer whose participant missed the node's action server):
    the node counts as not reached, and once a look sees it the listeners are told."""
    _launch(launch_task_manager, topic_prefix)
    watch = LostWatch(connection, serving=False)
    assert connection.wait_matched({ACTIVE_TASKS_TOPIC}, TIMEOUT_SEC)
    watch.start()

    assert watch.told.get(timeout=TIMEOUT_SEC) >= 1.0  # lost_sec, then the grace


def test_a_client_counts_the_node_as_serving_it_only_while_each_service_it_used_met_it(
    launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    """What the client's lost check is given as `serving`: its ExecuteTask server and every
    service the client has used (here one the node never serves stands for a service its
    participant missed)."""
    _launch(launch_task_manager, topic_prefix)
    with TaskManagerClient('serving_services', timeout_sec=TIMEOUT_SEC) as client:
        client.wait_until_available(services=['/task_manager/get_task_states'])
        served_before = client._served()

        client._services._client(GetTaskStates, f'{topic_prefix}/never_served')

        assert served_before and not client._served()
