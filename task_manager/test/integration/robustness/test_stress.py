"""Stress: concurrent clients fire a seeded mix of ~300 requests at one Task Manager.

Checked from the outside only: one /task_manager/results message and one ExecuteTask result
per request, and both agree; never two blocking tasks IN_PROGRESS at once; the active list
empties; the node's thread count stays bounded while more than a hundred tasks run.

The mix of requests and the scripted servers that end each goal as its Fibonacci `order`
says are testing/request_mix.py's. Set STRESS_SEED to replay another mix.
"""

import json
import os
import random
import threading
import time
from collections import Counter
from dataclasses import dataclass
from typing import Any, TypeVar

import psutil
from action_msgs.msg import GoalStatus
from rclpy.action.client import ActionClient
from task_manager_msgs.action import ExecuteTask
from test_msgs.action import Fibonacci

from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.testing.harness import (
    RosHarness,
    TopicRecorder,
    WaitTimeoutError,
    wait_for_future,
)
from task_manager.testing.probe import execute_task_client, warm_up
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.request_mix import GoalScript, OutcomeServer, Request, plan
from task_manager.testing.servers import CancelPolicy, ScriptedActionServer

T = TypeVar('T')
SEED = int(os.environ.get('STRESS_SEED', '20240611'))
CLIENTS = 4
BLOCKING_NAMES = frozenset({'nav', 'spin'})
IGNORE_CANCELS = frozenset({'spin', 'photo'})
"""The servers that accept a cancel and run on (the Task Manager's cancel_timeout ends them)."""
PEAK_IN_FLIGHT = 100
MAX_THREADS = 30
IGNORED_CANCEL_TIMEOUT_SEC = 0.3
SEND_TIMEOUT_SEC = 10.0
END_TIMEOUT_SEC = 20.0
BARRIER_ID = 'stress-barrier'
BARRIER_TASK = '__barrier__'


@dataclass
class Reply:
    request: Request
    goal_status: int
    result: Any


# ---- clients and observers -------------------------------------------------------------------


class StressClient:
    """One ExecuteTask client, sending its share of the stream from its own thread."""

    def __init__(self, ros: RosHarness, number: int, requests: list[Request]) -> None:
        self.number = number
        self.requests = requests
        self._ros = ros
        self.client: ActionClient[Any, Any, Any] = execute_task_client(ros)
        self.pending: list[tuple[Request, Any]] = []  # (request, result future)
        self.error: BaseException | None = None
        self.sent = threading.Event()
        self._thread = threading.Thread(target=self._send_all, name=f'stress-client-{number}')

    def destroy(self) -> None:
        self._ros.on_executor(self.client.destroy)

    def warm_up(self) -> None:
        """One round trip, so that DDS has matched this client's reply paths before the stream."""
        assert wait_until_ready(self.client.server_is_ready, SEND_TIMEOUT_SEC), 'no execute_task'
        warm_up(self.client)

    def start(self) -> None:
        self._thread.start()

    def _send_all(self) -> None:
        try:
            for request in self.requests:
                goal = ExecuteTask.Goal(
                    task_id=request.task_id,
                    task_name=request.task_name,
                    source=f'stress-client-{self.number}',
                    task_data=request.task_data,
                )
                handle = wait_for_future(
                    self._ros.send_goal(self.client, goal),
                    SEND_TIMEOUT_SEC,
                    f'goal {request.index}',
                )
                assert handle.accepted, f'goal {request.index} not accepted'
                self.pending.append((request, handle.get_result_async()))
        except BaseException as error:  # reported by the test thread
            self.error = error
        finally:
            self.sent.set()

    def wait_sent(self, timeout_sec: float) -> None:
        if not self.sent.wait(timeout_sec):
            raise WaitTimeoutError(f'client {self.number} still sending after {timeout_sec} s')
        self._thread.join(timeout_sec)
        if self.error is not None:
            raise self.error

    def replies(self, deadline: float) -> list[Reply]:
        replies = []
        for request, future in self.pending:
            remaining = max(0.1, deadline - time.monotonic())
            response = wait_for_future(future, remaining, f'result of request {request.index}')
            replies.append(Reply(request, response.status, response.result))
        return replies


class ActiveTasksWatch:
    """Follows /task_manager/active_tasks and samples the node's threads at every change."""

    def __init__(self, active: TopicRecorder, pid: int) -> None:
        self._active = active
        self._process = psutil.Process(pid)
        self.max_in_flight = 0
        self.max_threads = self._process.num_threads()
        self.threads_at_max_in_flight = self.max_threads
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._follow, name='active-tasks-watch')
        self._thread.start()

    def sample_threads(self) -> int:
        threads = self._process.num_threads()
        self.max_threads = max(self.max_threads, threads)
        return threads

    def _follow(self) -> None:
        seen = 0
        while not self._stop.is_set():

            def newer(msgs: list[Any], seen: int = seen) -> tuple[int, Any] | None:
                return (len(msgs), msgs[-1]) if len(msgs) > seen else None

            try:
                seen, latest = self._active.wait_until(newer, 0.5, 'an active_tasks message')
            except WaitTimeoutError:
                continue
            threads = self.sample_threads()
            if len(latest.active_tasks) > self.max_in_flight:
                self.max_in_flight = len(latest.active_tasks)
                self.threads_at_max_in_flight = threads

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(5.0)


def _in_progress(message: Any) -> list[Any]:
    return [t for t in message.active_tasks if t.task_status == 'IN_PROGRESS']


# ---- the test --------------------------------------------------------------------------------


def test_concurrent_mixed_requests_are_each_answered_once_and_consistently(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    rng = random.Random(SEED)
    requests = plan(rng)
    script = GoalScript()
    servers = {
        name: OutcomeServer(
            ros.node,
            Fibonacci,
            f'{topic_prefix}/{name}',
            cancel_policy=CancelPolicy.IGNORE if name in IGNORE_CANCELS else CancelPolicy.END,
            on_goal=script.on_goal,
        )
        for name in ('nav', 'spin', 'single', 'photo')
    }
    tm = launch_task_manager(
        {
            'nav': action_task('nav', f'{topic_prefix}/nav', blocking=True, cancel_on_stop=True),
            'spin': action_task(
                'spin',
                f'{topic_prefix}/spin',
                blocking=True,
                cancel_on_stop=True,
                cancel_timeout=IGNORED_CANCEL_TIMEOUT_SEC,
            ),
            'single': action_task('single', f'{topic_prefix}/single'),
            'photo': action_task(
                'photo',
                f'{topic_prefix}/photo',
                reentrant=True,
                cancel_timeout=IGNORED_CANCEL_TIMEOUT_SEC,
            ),
        }
    )
    clients = [StressClient(ros, n, requests[n::CLIENTS]) for n in range(CLIENTS)]
    watch = ActiveTasksWatch(tm.active, tm.process.process.pid)
    try:
        for client in clients:
            client.warm_up()
        began = time.monotonic()
        for client in clients:
            client.start()
        for client in clients:
            client.wait_sent(END_TIMEOUT_SEC)

        # every held photo runs now: the peak, with the threads it takes
        tm.active.wait_until(
            lambda msgs: msgs and len(msgs[-1].active_tasks) >= PEAK_IN_FLIGHT,
            END_TIMEOUT_SEC,
            f'{PEAK_IN_FLIGHT} tasks in flight',
        )
        threads_at_peak = watch.sample_threads()
        drained = script.drain()

        deadline = time.monotonic() + END_TIMEOUT_SEC
        replies = [reply for client in clients for reply in client.replies(deadline)]
        tm.active.wait_until(
            lambda msgs: msgs and not msgs[-1].active_tasks, END_TIMEOUT_SEC, 'no active task'
        )
        wall_sec = time.monotonic() - began
        # results are published in order: once the barrier's is in, every earlier one is
        barrier = tm.run(BARRIER_TASK, task_id=BARRIER_ID)
        assert barrier.error_code == 'unknown_task'
        tm.wait_result_message(BARRIER_ID)
        threads_at_end = watch.sample_threads()
    finally:
        watch.stop()
        for client in clients:
            client.destroy()

    actives = tm.active.snapshot()
    max_in_flight = max(watch.max_in_flight, *(len(m.active_tasks) for m in actives))
    print(
        f'\nstress seed {SEED}: {len(replies)} requests from {len(clients)} clients in '
        f'{wall_sec:.1f} s; max in flight {max_in_flight}; threads: max {watch.max_threads}, '
        f'at peak {threads_at_peak}, at end {threads_at_end}; {drained} goals drained; '
        f'outcomes {dict(Counter((r.result.task_status, r.result.error_code) for r in replies))}; '
        'goals (received, rejected) by server '
        + str({n: (len(s.goals.items), len(s.rejected.items)) for n, s in servers.items()})
    )

    # one ExecuteTask result per request, in the goal state its status calls for
    requests_per_id = Counter(r.task_id for r in requests)
    assert len(replies) == len(requests)
    for reply in replies:
        result = reply.result
        if reply.request.task_id:
            assert result.task_id == reply.request.task_id
        if reply.request.expected is not None:
            assert (result.task_status, result.error_code) == reply.request.expected, reply
        expected_goal_status = (
            GoalStatus.STATUS_SUCCEEDED
            if result.task_status == 'DONE'
            else GoalStatus.STATUS_ABORTED
        )
        assert reply.goal_status == expected_goal_status, reply
        if result.error_code == 'duplicate_id':
            # the copy may reach the node before its original: either can be the duplicate
            assert requests_per_id[result.task_id] > 1 and result.task_status == 'ERROR', reply
    assert any(r.result.error_code == 'duplicate_id' for r in replies)

    # one /results message per request, agreeing with its ExecuteTask result
    results = [m for m in tm.results.snapshot() if m.task_name != BARRIER_TASK]
    replies_by_id: dict[str, list[Reply]] = {}
    for reply in replies:
        replies_by_id.setdefault(reply.result.task_id, []).append(reply)
    # subtasks without an id in the request (the invalid ones) are named by their mission's rows
    subtask_ids = {s for r in requests for s in r.subtask_ids} | {
        row['task_id']
        for reply in replies
        if reply.request.kind == 'bad_data'
        for row in json.loads(reply.result.task_result).get('mission_results', [])
    }
    published_by_id: dict[str, list[Any]] = {}
    for message in results:
        published_by_id.setdefault(message.task_id, []).append(message)
    assert set(published_by_id) <= set(replies_by_id) | subtask_ids
    for task_id, its_replies in replies_by_id.items():
        published = published_by_id.get(task_id, [])
        assert Counter((m.task_status, m.error_code) for m in published) == Counter(
            (r.result.task_status, r.result.error_code) for r in its_replies
        ), task_id
        assert all(m.source.startswith('stress-client-') for m in published), task_id

    # mission subtasks: one result for each that ran, as the mission's row says
    for reply in replies:
        if reply.request.kind != 'mission':
            continue
        # no rows when the mission never started (e.g. replaced while it waited)
        rows = json.loads(reply.result.task_result).get('mission_results')
        if rows is None:
            assert not any(s in published_by_id for s in reply.request.subtask_ids), reply
            continue
        assert [row['task_id'] for row in rows] == list(reply.request.subtask_ids)
        for row in rows:
            published = published_by_id.get(row['task_id'], [])
            if row['task_status'] == 'RECEIVED':
                assert published == [], row
            else:
                assert [(m.task_status, m.source) for m in published] == [
                    (row['task_status'], 'Mission')
                ], row

    # never two blocking tasks at once; the list empties; threads stay bounded
    for message in actives:
        blocking = [t.task_id for t in _in_progress(message) if t.task_name in BLOCKING_NAMES]
        assert len(blocking) <= 1, blocking
    assert not actives[-1].active_tasks
    assert max_in_flight >= PEAK_IN_FLIGHT
    assert watch.max_threads <= MAX_THREADS
    assert threads_at_end <= MAX_THREADS


# ---- found by the stress test --------------------------------------------------------------


def test_a_task_starts_when_the_conflicting_task_fails_to_start(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    ScriptedActionServer(
        ros.node, Fibonacci, f'{topic_prefix}/nav', on_goal=lambda goal: goal.succeed()
    )
    tm = launch_task_manager(
        {
            # no server: its start fails after server_wait_timeout
            'ghost': action_task('ghost', f'{topic_prefix}/ghost', blocking=True),
            'nav': action_task('nav', f'{topic_prefix}/nav', blocking=True),
        },
        server_wait_timeout=0.5,
    )
    ghost = tm.send('ghost', {'order': 1}, task_id='ghost')

    nav = tm.run('nav', {'order': 1}, task_id='nav')

    # ghost was cancelled (by nav) before its start failed: it ends CANCELED, saying why
    ghost_result = tm.result_of(ghost).result
    assert 'is not available' in json.loads(ghost_result.task_result)['error']
    assert (ghost_result.task_status, nav.task_status, nav.error_code) == (
        'CANCELED',
        'DONE',
        '',
    )
