"""Deciding what runs (issue 29): dispatch beside a full queue, and the queue's handover.

The node is restarted with two more tasks: `bench/base`, on the hold server, holding the
resource `base`, and `bench/arm`, on the instant Fibonacci server, holding `arm`. A
`bench/base` goal holds `base` as long as its server keeps it (until /bench/release_goals),
and QUEUED_TASKS more `bench/base` requests wait for it (StartTask goals, on_conflict queue).

1. Dispatch: the round trip of an instant `bench/arm` task (another resource) while the
   QUEUED_TASKS wait, vs while none waits (a holder holding `base` all the same); the samples
   without a queue are taken half before the queue is filled and half after it is drained,
   so that drift hits both alike.
2. Handover: the holder is released; the first queued task starts, is released in turn, and
   so on through the queue. Each sample is the node's own stamps (GetTaskStates): from the
   `ended` of one task on `base` to the `started` (its goal accepted by its server) of the
   next. The baseline is a `bench/base` request's own `received` to `started` while `base`
   is free: the same start on the same server, without a queue before it.
Finally the node is restarted with the default parameters.
"""

import contextlib
import itertools
import statistics
import time
import uuid
from dataclasses import dataclass
from typing import Any

from rclpy.task import Future

from bench.harness import config
from bench.harness.client import SeenEvent, TaskEventsWatcher, error_code, task_status
from bench.harness.context import BenchContext
from bench.harness.lean_action import LeanActionClient
from bench.harness.replies import BenchError, Reply, wait_reply
from bench.harness.report import Row
from bench.harness.stats import Summary, ratio, wait_all
from bench.node.schedules import seconds, task_states
from task_manager.core.names import START_TASK_ACTION
from task_manager.testing.process import action_task
from task_manager_msgs.action import StartTask
from task_manager_msgs.msg import TaskOptions

BASE_TASK = 'bench/base'
ARM_TASK = 'bench/arm'
QUEUED_TASKS = 100
EMPTY_SAMPLES = 150
"""Dispatch samples without a queue, before the queue is filled and again after it is drained."""
QUEUED_SAMPLES = 300
PROFILED_SAMPLES = 300
FREE_STARTS = 15
"""Baseline starts of `bench/base` on a free `base`, before the queue and again after it."""
DISPATCH_TARGET = 1.2
HANDOVER_TARGET_MS = 5.0
STEP_TIMEOUT_SEC = 10.0
EVENTS_WARM_UP_ATTEMPTS = 5
EVENTS_WARM_UP_TIMEOUT_SEC = 2.0


def node_parameters() -> dict[str, object]:
    """The bench's tasks, plus `bench/base` and `bench/arm` (both reentrant: a resource alone
    decides what waits)."""
    tasks = list(config.node_parameters()['tasks'])
    return {
        'tasks': [*tasks, 'base', 'arm'],
        'base': action_task(BASE_TASK, config.HOLD_TOPIC, resources=['base'], reentrant=True),
        'arm': action_task(ARM_TASK, config.FIBONACCI_TOPIC, resources=['arm'], reentrant=True),
    }


def start_task_goal(task_id: str, on_conflict: str = '') -> StartTask.Goal:
    return StartTask.Goal(
        task_id=task_id,
        task_name=BASE_TASK,
        source='bench',
        task_data=config.FIBONACCI_DATA,
        options=TaskOptions(on_conflict=on_conflict),
    )


@dataclass(frozen=True)
class Handover:
    """The drain of the queue as the bench saw it."""

    started_ids: list[str]
    """The queued tasks in the order they started."""
    seen_ms: list[float]
    """From the bench's release request to the bench seeing the next task's STARTED event."""


class AdmissionBench:
    """The StartTask client, the event watcher and the ids of the `bench/base` tasks run."""

    def __init__(self, ctx: BenchContext) -> None:
        self.ctx = ctx
        node = ctx.client.harness.node
        self.start_task = LeanActionClient(node, StartTask, START_TASK_ACTION)
        self.events = TaskEventsWatcher(ctx.client.harness)
        self.free_ids: list[str] = []

    def destroy(self) -> None:
        self.start_task.destroy()
        self.events.destroy()

    def connect(self) -> None:
        """StartTask answers, and the node's task events reach the bench."""
        if not self.start_task.wait_for_server(config.CONNECT_TIMEOUT_SEC):
            raise BenchError(f'{START_TASK_ACTION} not available')
        for attempt in range(EVENTS_WARM_UP_ATTEMPTS):
            task_id = f'bench-admission-warm-up-{attempt}'
            goal = StartTask.Goal(task_id=task_id, task_name='__bench_warm_up__', source='bench')
            try:
                wait_reply(self.start_task.send_goal(goal), task_id, EVENTS_WARM_UP_TIMEOUT_SEC)
                self.events.wait_event('ENDED', task_id, EVENTS_WARM_UP_TIMEOUT_SEC)
                return
            except BenchError:
                print(f'[bench] StartTask warm-up {attempt + 1} lost, retrying', flush=True)
        raise BenchError(f'no StartTask round trip and event in {EVENTS_WARM_UP_ATTEMPTS} tries')

    def send(self, task_id: str, on_conflict: str = '') -> Future[Any]:
        return self.start_task.send_goal(start_task_goal(task_id, on_conflict))

    def wait_started(self, task_ids: set[str], count: int) -> float:
        """Wait until `count` of `task_ids` have STARTED; when the bench saw the last of them."""
        started: list[SeenEvent] = []

        def enough(seen: list[SeenEvent]) -> bool:
            started[:] = [e for e in seen if e.event == 'STARTED' and e.task_id in task_ids]
            return len(started) >= count

        self.events.wait_until(enough, STEP_TIMEOUT_SEC, f'{count} of {len(task_ids)} started')
        return started[count - 1].at

    def hold_base(self, task_id: str) -> Future[Any]:
        """A `bench/base` task that holds `base` until released; returns its reply future."""
        replied = self.send(task_id)
        self.events.wait_event('STARTED', task_id, STEP_TIMEOUT_SEC)
        return replied

    def release(self) -> None:
        """End the one `bench/base` goal its server holds."""
        reply = wait_reply(self.ctx.client.call_trigger(self.ctx.client.release_goals), 'release')
        if reply.response.message != 'released 1 goal(s)':
            raise BenchError(f'release: {reply.response.message} (expected 1 goal)')

    def free_starts(self, count: int) -> None:
        """`count` `bench/base` tasks, each started on a free `base`, then released."""
        for _ in range(count):
            task_id = f'bench-admission-free-{uuid.uuid4().hex[:8]}'
            replied = self.hold_base(task_id)
            self.release()
            expect_done(wait_reply(replied, task_id), task_id)
            self.free_ids.append(task_id)

    def fill_queue(self, count: int) -> tuple[list[str], dict[str, Future[Any]]]:
        """`count` requests queued for `base`: their ids in the order the node queued them,
        and their reply futures by id."""
        ids = [f'bench-admission-queued-{uuid.uuid4().hex[:8]}' for _ in range(count)]
        replies = {task_id: self.send(task_id, 'queue') for task_id in ids}
        wanted = set(ids)
        self.events.wait_until(
            lambda seen: (
                sum(1 for e in seen if e.event == 'QUEUED' and e.task_id in wanted) >= count
            ),
            STEP_TIMEOUT_SEC,
            f'{count} tasks queued',
        )
        queued = [e.task_id for e in self.events.take() if e.event == 'QUEUED']
        return [task_id for task_id in queued if task_id in wanted], replies

    def drain(self, queued_ids: list[str], replies: dict[str, Future[Any]]) -> Handover:
        """Release the holder, then each queued task once it has started, one after another."""
        wanted = set(queued_ids)
        early = [
            e.task_id for e in self.events.take() if e.event == 'STARTED' and e.task_id in wanted
        ]
        if early:
            raise BenchError(
                f'{len(early)} queued tasks started before their turn, e.g. {early[0]}'
            )
        seen_ms = []
        for index in range(len(queued_ids)):
            released_at = time.perf_counter()
            self.release()
            seen_ms.append((self.wait_started(wanted, index + 1) - released_at) * 1e3)
        self.release()
        done = wait_all(list(replies.values()), config.BURST_TIMEOUT_SEC, 'queued tasks')
        for reply, task_id in zip(done, replies, strict=True):
            expect_done(reply, task_id)
        started = [e.task_id for e in self.events.take() if e.event == 'STARTED']
        return Handover([t for t in started if t in wanted], seen_ms)


def expect_done(reply: Reply, task_id: str) -> None:
    if task_status(reply) != 'DONE':
        raise BenchError(f'{task_id} ended {task_status(reply)!r} {error_code(reply)!r}')


def arm_samples(ctx: BenchContext, count: int) -> list[float]:
    """Round trips of instant `bench/arm` tasks, one after another."""
    return [ctx.task_latency_ms(ARM_TASK, config.FIBONACCI_DATA) for _ in range(count)]


def handover_ms(ctx: BenchContext, holder_id: str, started_ids: list[str]) -> list[float]:
    """From each task on `base` ended to the next one started, by the node's stamps."""
    chain = [holder_id, *started_ids]
    by_id = {state.task_id: state for state in task_states(ctx, chain)}
    return [
        (seconds(by_id[after].started) - seconds(by_id[before].ended)) * 1e3
        for before, after in itertools.pairwise(chain)
    ]


def free_start_ms(ctx: BenchContext, task_ids: list[str]) -> list[float]:
    """From received to started, by the node's stamps, of tasks that found `base` free."""
    return [
        (seconds(state.started) - seconds(state.received)) * 1e3
        for state in task_states(ctx, task_ids)
    ]


def with_empty_queue(ctx: BenchContext, bench: AdmissionBench, holder_id: str) -> list[float]:
    """Dispatch samples while `holder_id` holds `base` and nothing waits for it."""
    held = bench.hold_base(holder_id)
    ctx.settle()
    samples = arm_samples(ctx, EMPTY_SAMPLES)
    bench.release()
    expect_done(wait_reply(held, holder_id), holder_id)
    return samples


def measure(ctx: BenchContext, bench: AdmissionBench) -> None:
    bench.connect()
    arm_samples(ctx, config.WARM_UP_SAMPLES)
    bench.free_starts(FREE_STARTS)
    empty_ms = with_empty_queue(ctx, bench, 'bench-admission-holder-empty-1')
    holder_id = 'bench-admission-holder-queue'
    held = bench.hold_base(holder_id)
    queued_ids, replies = bench.fill_queue(QUEUED_TASKS)
    ctx.settle()
    queued_ms = arm_samples(ctx, QUEUED_SAMPLES)
    if held.done() or any(reply.done() for reply in replies.values()):
        raise BenchError('a task on base ended during the samples: they measured no queue')
    if ctx.profiling:  # more samples, not measured: sampling pauses the node
        ctx.settle()
        with ctx.profiled(f'admission: {PROFILED_SAMPLES} instant tasks, {QUEUED_TASKS} queued'):
            arm_samples(ctx, PROFILED_SAMPLES)
    ctx.settle()
    handover = bench.drain(queued_ids, replies)
    expect_done(wait_reply(held, holder_id), holder_id)
    bench.free_starts(FREE_STARTS)
    empty_ms += with_empty_queue(ctx, bench, 'bench-admission-holder-empty-2')

    empty, queued = Summary.of(empty_ms), Summary.of(queued_ms)
    factor = ratio(queued.median, empty.median)
    handed = Summary.of(handover_ms(ctx, holder_id, handover.started_ids))
    free = Summary.of(free_start_ms(ctx, bench.free_ids))
    seen = Summary.of(handover.seen_ms)
    ctx.report.add(
        Row(
            benchmark='admission dispatch',
            metric=(
                f'round trip ms, a task on another resource, {QUEUED_TASKS} queued, '
                f'med / p95, n={queued.count}'
            ),
            measured=queued.text(),
            baseline=f'{empty.text()} none queued',
            ratio=f'{factor:.2f}x',
            target=f'<= {DISPATCH_TARGET}x',
            met=factor <= DISPATCH_TARGET,
        ),
        Row(
            benchmark='admission handover',
            metric=(
                f'ms from a task ended to the next queued started (node stamps), med / p95, '
                f'n={handed.count}'
            ),
            measured=handed.text(),
            baseline=f'{free.text()} received -> started, free',
            ratio=f'{ratio(handed.median, free.median):.2f}x',
            target=f'<= {HANDOVER_TARGET_MS:g} ms',
            met=handed.median <= HANDOVER_TARGET_MS,
        ),
    )
    in_order = 'yes' if handover.started_ids == queued_ids else 'NO'
    before, after = empty_ms[:EMPTY_SAMPLES], empty_ms[EMPTY_SAMPLES:]
    ctx.report.note(
        f'admission handover: from a release request of the bench to the next STARTED event '
        f'it saw (the server ends the goal, its result reaches the node, the event the bench) '
        f'{seen.text()} ms med / p95; the {QUEUED_TASKS} queued tasks started in the order '
        f'queued: {in_order}'
    )
    ctx.report.note(
        f'admission dispatch: none queued, medians {statistics.median(before):.2f} ms before '
        f'the queue was filled and {statistics.median(after):.2f} ms after it was drained'
    )


def run(ctx: BenchContext) -> None:
    ctx.restart_node('task_manager_admission', **node_parameters())
    bench = AdmissionBench(ctx)
    try:
        measure(ctx, bench)
    finally:
        bench.destroy()
        # a goal a failed step left held would be counted by the next benchmark's release
        with contextlib.suppress(BenchError):
            wait_reply(ctx.client.call_trigger(ctx.client.release_goals), 'release')
        ctx.restart_node()
