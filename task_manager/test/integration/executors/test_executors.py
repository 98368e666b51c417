"""The executors of the node and the client. WakelessExecutor: a message costs one wait set.
ParkingExecutor: a coroutine waiting on a future is not stepped until the future completes;
woken tasks run, and waiting requests and responses are taken, before the executor waits
again, without starving ready entities."""

import os
import threading
import time
from collections.abc import Callable, Coroutine, Iterator
from typing import Any

import pytest
import rclpy
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.client import Client
from rclpy.executors import SingleThreadedExecutor
from rclpy.task import Future
from std_srvs.srv import Trigger
from test_msgs.msg import Empty

from task_manager.rclpy_tools.futures import resolved
from task_manager.rclpy_tools.qos import DEEP_RELIABLE
from task_manager.rclpy_tools.reusable_wait_set import ReusableWaitSet
from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.rclpy_tools.wakeless_executor import WakelessExecutor
from task_manager.ros import parking_executor
from task_manager.ros.parking_executor import ParkingExecutor, spawn_after_turn

pytestmark = pytest.mark.ros
UNRELATED_WAKE_UPS = 20
CHAIN_LENGTH = 20
BURST = 50
MESSAGES = 5
IDLE_WAIT_SEC = 0.02


class CountingFuture(Future[int]):
    """Counts how often an awaiting coroutine checked it (once per step of the coroutine)."""

    def __init__(self) -> None:
        super().__init__()
        self.checks = 0

    def _pending(self) -> bool:
        self.checks += 1
        return super()._pending()


@pytest.fixture
def spun_node(ros_context: None) -> Iterator[tuple[ParkingExecutor, rclpy.node.Node]]:
    """A node on a ParkingExecutor, both destroyed after the test."""
    parking_executor.install()
    executor = ParkingExecutor()
    node = rclpy.create_node(f'parking_{os.getpid()}')
    executor.add_node(node)
    yield executor, node
    executor.shutdown()
    node.destroy_node()


def test_a_waiting_coroutine_is_stepped_only_when_its_future_completes(ros_context: None) -> None:
    parking_executor.install()
    executor = ParkingExecutor()
    future = CountingFuture()
    seen: list[int | None] = []

    async def waiter() -> None:
        seen.append(await future)

    task = executor.create_task(waiter)
    executor.spin_once(timeout_sec=0.0)  # runs it up to the await
    checks_at_the_await = future.checks
    for _ in range(UNRELATED_WAKE_UPS):
        executor.create_task(lambda: None)
        executor.spin_once(timeout_sec=0.0)
    assert future.checks == checks_at_the_await  # rclpy's executor steps it at each wake-up

    threading.Thread(target=future.set_result, args=(7,)).start()  # from another thread
    executor.spin_until_future_complete(task, timeout_sec=5.0)
    assert task.done() and seen == [7]
    executor.shutdown()


def test_a_coroutine_awaiting_a_future_already_done_goes_on_at_once(ros_context: None) -> None:
    parking_executor.install()
    executor = ParkingExecutor()
    done: Future[int] = Future()
    done.set_result(3)

    async def twice() -> int:
        return (await done or 0) + (await done or 0)

    task = executor.create_task(twice)
    executor.spin_until_future_complete(task, timeout_sec=5.0)
    assert task.result() == 6
    executor.shutdown()


def test_an_async_service_callback_waiting_on_a_future_is_parked_too(
    spun_node: tuple[ParkingExecutor, rclpy.node.Node],
) -> None:
    executor, node = spun_node
    future = CountingFuture()
    entered = threading.Event()

    async def answer(_: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        entered.set()
        response.success = bool(await future)
        return response

    name = f'/parking_{os.getpid()}/answer'
    node.create_service(Trigger, name, answer, callback_group=ReentrantCallbackGroup())
    client: Client[Trigger.Request, Trigger.Response] = node.create_client(Trigger, name)
    assert wait_until_ready(client.service_is_ready, 5.0)
    reply = client.call_async(Trigger.Request())
    deadline = time.monotonic() + 5.0
    while not entered.is_set() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)
    assert entered.is_set()
    checks_at_the_await = future.checks
    for _ in range(UNRELATED_WAKE_UPS):
        executor.create_task(lambda: None)
        executor.spin_once(timeout_sec=0.0)
    assert future.checks == checks_at_the_await  # rclpy's handler task steps it at each wake-up

    future.set_result(1)
    executor.spin_until_future_complete(reply, timeout_sec=5.0)
    response = reply.result()
    assert reply.done() and response is not None and response.success


def test_coroutines_woken_by_each_other_run_before_the_executor_waits_again(
    spun_node: tuple[ParkingExecutor, rclpy.node.Node],
) -> None:
    executor, node = spun_node
    order: list[str] = []
    guard = node.create_guard_condition(lambda: order.append('ready entity'))
    links: list[Future[None]] = [Future() for _ in range(CHAIN_LENGTH + 1)]

    async def link(index: int) -> None:
        await links[index]
        order.append(f'link {index}')
        if index == 0:
            guard.trigger()  # ready at the next wait
        links[index + 1].set_result(None)

    for index in range(CHAIN_LENGTH):
        executor.create_task(link, index)
    for _ in range(CHAIN_LENGTH):
        executor.spin_once(timeout_sec=0.0)  # each up to its await, where it parks
    executor.create_task(lambda: links[0].set_result(None))
    executor.spin_until_future_complete(links[CHAIN_LENGTH], timeout_sec=5.0)
    executor.spin_once(timeout_sec=1.0)
    # rclpy's executor waits on its wait set (and calls the ready entity) between two links
    assert order == [*(f'link {i}' for i in range(CHAIN_LENGTH)), 'ready entity']


def test_tasks_that_keep_waking_each_other_do_not_starve_a_ready_entity(
    spun_node: tuple[ParkingExecutor, rclpy.node.Node],
) -> None:
    executor, node = spun_node
    called = threading.Event()
    guard = node.create_guard_condition(called.set)
    steps = [0]

    def again() -> None:
        steps[0] += 1
        executor.create_task(again)

    executor.create_task(again)
    guard.trigger()
    for _ in range(3 * parking_executor.RUN_AHEAD_LIMIT):
        executor.spin_once(timeout_sec=0.0)
        if called.is_set():
            break
    assert called.is_set() and steps[0] <= parking_executor.RUN_AHEAD_LIMIT + 1


def test_a_coroutine_in_resolved_goes_on_when_its_future_completes_with_no_wake_up_task(
    spun_node: tuple[ParkingExecutor, rclpy.node.Node],
) -> None:
    executor, node = spun_node
    assert executor.resumes_waiters  # resolved() queues no wake-up task on it
    future: Future[int] = Future()
    task = executor.create_task(resolved, node, future)
    executor.spin_once(timeout_sec=0.0)  # up to its await, where it parks
    threading.Thread(target=future.set_result, args=(5,)).start()
    started = time.monotonic()
    executor.spin_until_future_complete(task, timeout_sec=5.0)
    assert task.result() == 5 and time.monotonic() - started < 1.0


class WaitSetCount:
    """Counts the waits of rclpy's executors (a wait set built for each, through the module
    they make them with) and of ours (their reusable wait set's `wait`); nothing else about
    them changes."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.count = 0
        real = rclpy.executors._rclpy  # type: ignore[attr-defined]  # the binding it patches
        counter = self
        wait = ReusableWaitSet.wait

        def counted_wait(wait_set: ReusableWaitSet, timeout_nsec: int) -> Any:
            counter.count += 1
            return wait(wait_set, timeout_nsec)

        monkeypatch.setattr(ReusableWaitSet, 'wait', counted_wait)

        class Counting:
            def __getattr__(self, name: str) -> Any:
                return getattr(real, name)

            def WaitSet(self, *args: Any) -> Any:  # noqa: N802 (rclpy's name)
                counter.count += 1
                return real.WaitSet(*args)

        monkeypatch.setattr(rclpy.executors, '_rclpy', Counting())


def turns_to_answer_a_burst(
    executor: SingleThreadedExecutor,
    name: str,
    waits: WaitSetCount,
    on_request: Callable[[rclpy.node.Node], None] = lambda _: None,
) -> int:
    """Wait sets built from BURST requests sent at once to all their responses."""
    node = rclpy.create_node(f'{name}_{os.getpid()}')
    service = f'/{name}_{os.getpid()}'

    def answer(_: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        on_request(node)
        return response

    node.create_service(Trigger, service, answer, qos_profile=DEEP_RELIABLE)
    client: Client[Any, Any] = node.create_client(Trigger, service, qos_profile=DEEP_RELIABLE)
    assert wait_until_ready(client.service_is_ready, 5.0)
    executor.add_node(node)
    replies = [client.call_async(Trigger.Request()) for _ in range(BURST)]
    everything: Future[None] = Future()
    remaining = [BURST]

    def one_more(_: Future[Any]) -> None:
        remaining[0] -= 1
        if not remaining[0]:
            everything.set_result(None)

    for reply in replies:
        reply.add_done_callback(one_more)
    before = waits.count
    executor.spin_until_future_complete(everything, timeout_sec=10.0)
    turns = waits.count - before
    assert everything.done()
    executor.shutdown()
    node.destroy_node()
    return turns


def test_waiting_requests_and_responses_are_taken_in_the_turn_that_found_the_first(
    ros_context: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    parking_executor.install()
    # rclpy takes one request per service and one response per client per wait
    waits = WaitSetCount(monkeypatch)
    rclpy_turns = turns_to_answer_a_burst(SingleThreadedExecutor(), 'burst_rclpy', waits)
    parking_turns = turns_to_answer_a_burst(ParkingExecutor(), 'burst_parking', waits)
    assert rclpy_turns >= BURST and parking_turns <= BURST // 5, (rclpy_turns, parking_turns)


def test_what_is_spawned_after_the_turn_runs_once_the_waiting_requests_are_answered(
    ros_context: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    parking_executor.install()
    answered = [0]
    # how many requests had been answered each time the after-turn coroutine ran
    flushes: list[int] = []
    pending = [False]

    async def flush() -> None:
        pending[0] = False
        flushes.append(answered[0])

    def on_request(node: rclpy.node.Node) -> None:
        answered[0] += 1
        if not pending[0]:
            pending[0] = True
            spawn_after_turn(node, flush())

    turns_to_answer_a_burst(ParkingExecutor(), 'after_turn', WaitSetCount(monkeypatch), on_request)
    # as a task, it would run after each request (the run-ahead runs tasks first)
    assert flushes and flushes[-1] == BURST and len(flushes) <= BURST // 5, flushes


def done_when_run() -> tuple[Future[None], Callable[[], Coroutine[None, None, None]]]:
    """A future, and a coroutine function that completes it."""
    done: Future[None] = Future()

    async def finish() -> None:
        done.set_result(None)

    return done, finish


def test_work_done_within_its_turn_leaves_no_wake_up_behind(
    spun_node: tuple[ParkingExecutor, rclpy.node.Node], monkeypatch: pytest.MonkeyPatch
) -> None:
    """rclpy's handler wakes the executor twice, a new task and a new timer once each: every
    wake-up left behind costs a wait set with nothing ready after the turn that did the work."""
    executor, node = spun_node
    done, finish = done_when_run()

    def work() -> None:
        node.destroy_timer(node.create_timer(60.0, lambda: None))
        executor.create_task(finish)

    node.create_guard_condition(work).trigger()
    executor.spin_until_future_complete(done, timeout_sec=5.0)
    assert done.done()
    waits = WaitSetCount(monkeypatch)
    executor.spin_once(timeout_sec=0.05)
    assert waits.count == 1  # the one that times out


def test_what_is_spawned_after_the_turn_between_spins_runs_at_the_next_one(
    spun_node: tuple[ParkingExecutor, rclpy.node.Node],
) -> None:
    """No turn has found work to wait for: it must not wait for the next outside event."""
    executor, node = spun_node
    done, finish = done_when_run()
    spawn_after_turn(node, finish())
    started = time.monotonic()
    executor.spin_until_future_complete(done, timeout_sec=5.0)
    assert done.done() and time.monotonic() - started < 1.0


def test_what_is_spawned_after_a_turn_that_reached_its_run_ahead_limit_runs_at_once(
    spun_node: tuple[ParkingExecutor, rclpy.node.Node],
) -> None:
    """A turn whose run-ahead ends at the limit with only after-turn work left (the history
    flush that answers ExecuteTask): that work must not wait for the next outside event."""
    executor, node = spun_node
    done, finish = done_when_run()

    def work() -> None:
        for _ in range(parking_executor.RUN_AHEAD_LIMIT):
            executor.create_task(lambda: None)
        spawn_after_turn(node, finish())

    node.create_guard_condition(work).trigger()
    started = time.monotonic()
    executor.spin_until_future_complete(done, timeout_sec=5.0)
    assert done.done() and time.monotonic() - started < 1.0, time.monotonic() - started


def waits_for_messages(executor: SingleThreadedExecutor, waits: WaitSetCount) -> int:
    """Wait sets built for MESSAGES, each published once the executor has gone idle after the
    one before (as a gateway's messages come: apart), the last idle wait included."""
    node = rclpy.create_node(f'messages_{os.getpid()}')
    topic = f'/messages_{os.getpid()}'
    received: list[Empty] = []
    node.create_subscription(Empty, topic, received.append, DEEP_RELIABLE)
    publisher = node.create_publisher(Empty, topic, DEEP_RELIABLE)
    assert wait_until_ready(lambda: publisher.get_subscription_count() == 1, 5.0)
    executor.add_node(node)
    before = waits.count
    for count in range(1, MESSAGES + 1):
        publisher.publish(Empty())
        deadline = time.monotonic() + 5.0
        while len(received) < count and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=5.0)
        executor.spin_once(timeout_sec=IDLE_WAIT_SEC)  # nothing comes: this wait times out
    built = waits.count - before
    assert len(received) == MESSAGES
    executor.shutdown()
    node.destroy_node()
    return built


def test_a_message_costs_one_wait_set(ros_context: None, monkeypatch: pytest.MonkeyPatch) -> None:
    """rclpy's handler wakes its executor twice (once the message is taken, once its callback
    has run): each message then costs one more wait set, with nothing ready."""
    waits = WaitSetCount(monkeypatch)
    rclpy_waits = waits_for_messages(SingleThreadedExecutor(), waits)
    wakeless_waits = waits_for_messages(WakelessExecutor(), waits)
    # per message: the wait that finds it, then the idle one; rclpy's woken one between
    assert rclpy_waits == 3 * MESSAGES and wakeless_waits == 2 * MESSAGES, (
        rclpy_waits,
        wakeless_waits,
    )
