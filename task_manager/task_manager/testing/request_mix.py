"""A seeded mix of requests for the stress test (task_manager/test/integration/robustness/
test_stress.py), and the scripted servers that end its goals as each request's Fibonacci
`order` says (see `encode`): at once, after a number of later goal arrivals at any server, or
when the test drains them after the stream."""

import json
import math
import random
import threading
from dataclasses import dataclass
from typing import Any

from rclpy.action.server import GoalResponse
from test_msgs.action import Fibonacci

from task_manager.testing.servers import ScriptedActionServer, ScriptedGoal

# key: kind of request, value: how many of them the stream holds (300 in all)
KIND_COUNTS = {
    'photo_held': 110,  # reentrant, held until the drain: the in-flight peak
    'photo': 25,  # reentrant, any outcome
    'nav': 25,  # blocking
    'spin': 25,  # blocking, ignores cancels
    'single': 30,  # same-name goals replace each other
    'mission': 15,
    'cancel': 20,  # system/cancel_task (or its alias) of earlier ids, known and unknown
    'stop': 6,
    'unknown': 12,
    'bad_data': 12,
    'duplicate': 20,  # the id of an earlier request, which may still be active
}
# Fibonacci `order` = outcome index * 1000 + hold; hold 0 ends at once, DRAIN at the drain.
OUTCOMES = ('succeed', 'abort', 'reject')
DRAIN = 999
UNKNOWN_NAMES = ('nope', 'system/nope', '', 'NAV', 'nav ', 'système/ünïcode')
BAD_DATA = (
    ('nav', '{"order": '),
    ('photo', '[]'),
    ('single', '{"order": "abc"}'),
    ('spin', '{}'),
    ('nav', '{"order": 2147483648}'),
    ('photo', ''),
    ('single', 'NaN'),
    ('system/mission', '{"subtasks": [{"task_name": "nope"}]}'),
    ('system/mission', '{"subtasks": [{"task_name": "system/mission"}]}'),
    ('system/cancel_task', 'null'),
    ('system/cancel_task', '{"cancelled_tasks": "x"}'),
    ('system/stop', '{"success": 1'),
)
DUPLICABLE = ('photo_held', 'photo', 'nav', 'spin', 'single', 'cancel', 'stop')


def encode(outcome: str, hold: int) -> int:
    """The Fibonacci `order` of a goal that ends with `outcome` after `hold` later arrivals."""
    return OUTCOMES.index(outcome) * 1000 + hold


def decode(order: int) -> tuple[str, int]:
    return OUTCOMES[order // 1000], order % 1000


@dataclass
class Request:
    index: int
    kind: str
    task_id: str
    task_name: str
    task_data: str
    subtask_ids: tuple[str, ...] = ()
    expected: tuple[str, str] | None = None
    """(status, error_code) when certain from the request alone."""


# ---- the scripted servers --------------------------------------------------------------------


class GoalScript:
    """Ends goals as their order says, on one clock of goal arrivals shared by all servers."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._arrivals = 0
        self._draining = False
        # (arrival count at which to end it, goal, outcome)
        self._held: list[tuple[float, ScriptedGoal, str]] = []

    def on_goal(self, goal: ScriptedGoal) -> None:
        outcome, hold = decode(goal.request.order)
        with self._lock:
            self._arrivals += 1
            due = [h for h in self._held if h[0] <= self._arrivals]
            self._held = [h for h in self._held if h[0] > self._arrivals]
            if hold and not self._draining:
                release_at = math.inf if hold == DRAIN else self._arrivals + hold
                self._held.append((release_at, goal, outcome))
            else:
                due.append((0, goal, outcome))
        for _, held_goal, held_outcome in due:
            _end(held_goal, held_outcome)

    def drain(self) -> int:
        """End every held goal, and from now on every new goal at once; return how many."""
        with self._lock:
            self._draining = True
            due, self._held = self._held, []
        for _, goal, outcome in due:
            _end(goal, outcome)
        return len(due)


def _end(goal: ScriptedGoal, outcome: str) -> None:
    if outcome == 'succeed':
        goal.succeed(Fibonacci.Result(sequence=[goal.request.order]))
    else:
        goal.abort()


class OutcomeServer(ScriptedActionServer):
    """A scripted server that also rejects the goals whose order says so."""

    def _goal(self, request: Any) -> GoalResponse:
        if decode(request.order)[0] == 'reject':
            self.rejected.add(request)
            return GoalResponse.REJECT
        return super()._goal(request)


# ---- the request stream ----------------------------------------------------------------------


def _server_order(rng: random.Random, max_hold: int) -> int:
    outcome = rng.choices(OUTCOMES, weights=(6, 3, 1))[0]
    if outcome == 'reject' or max_hold == 0 or rng.random() < 0.4:
        return encode(outcome, 0)
    return encode(outcome, rng.randint(1, max_hold))


def _order_data(order: int) -> str:
    return json.dumps({'order': order})


def _kinds(rng: random.Random) -> list[str]:
    """Every kind as often as KIND_COUNTS says, shuffled; no duplicate among the first ten."""
    kinds = [
        kind for kind, count in KIND_COUNTS.items() if kind != 'duplicate' for _ in range(count)
    ]
    rng.shuffle(kinds)
    for _ in range(KIND_COUNTS['duplicate']):
        kinds.insert(rng.randint(10, len(kinds)), 'duplicate')
    return kinds


def plan(rng: random.Random) -> list[Request]:
    """The stream of requests, each kind as often as KIND_COUNTS says, drawn from `rng`."""
    requests: list[Request] = []
    known_ids: list[str] = []  # every id so far, subtask ids included
    for index, kind in enumerate(_kinds(rng)):
        task_id = f'r{index:03d}'
        if kind == 'photo_held':
            order = encode(rng.choice(('succeed', 'abort')), DRAIN)
            request = Request(index, kind, task_id, 'photo', _order_data(order))
        elif kind in ('photo', 'nav', 'spin', 'single'):
            order = _server_order(rng, 40)
            request = Request(index, kind, task_id, kind, _order_data(order))
        elif kind == 'mission':
            subtasks: list[dict[str, Any]] = []
            for number in range(rng.randint(1, 3)):
                name = rng.choice(('nav', 'single', 'photo'))
                # photo ignores cancels: its subtasks end at once, so a mission cancel is quick
                order = _server_order(rng, 0 if name == 'photo' else 10)
                subtasks.append(
                    {
                        'task_id': f'{task_id}-s{number}',
                        'task_name': name,
                        'task_data': _order_data(order),
                        'allow_skipping': rng.random() < 0.5,
                    }
                )
            subtask_ids = tuple(s['task_id'] for s in subtasks)
            data = json.dumps({'subtasks': subtasks})
            request = Request(index, kind, task_id, 'system/mission', data, subtask_ids)
            known_ids += subtask_ids
        elif kind == 'cancel':
            recent = known_ids[-40:]
            ids = rng.sample(recent, min(len(recent), rng.randint(1, 3)))
            if rng.random() < 0.5:
                ids.append(f'ghost-{index}')
            name = rng.choice(('system/cancel_task', 'system/cancel_tasks'))
            data = json.dumps({'cancelled_tasks': ids})
            request = Request(index, kind, task_id, name, data)
        elif kind == 'stop':
            request = Request(index, kind, task_id, 'system/stop', '{}')
        elif kind == 'unknown':
            name = rng.choice((*UNKNOWN_NAMES, f'unknown-{index}'))
            data = _order_data(1)
            request = Request(index, kind, task_id, name, data, expected=('ERROR', 'unknown_task'))
        elif kind == 'bad_data':
            name, data = rng.choice(BAD_DATA)
            expected = ('ERROR', 'task_data_parsing_failed')
            request = Request(index, kind, task_id, name, data, expected=expected)
        else:  # duplicate: a copy of an earlier request, its id included
            candidates = [r for r in requests if r.kind in DUPLICABLE]
            held = [r for r in candidates if r.kind == 'photo_held']
            original = rng.choice(held if held and rng.random() < 0.6 else candidates)
            request = Request(index, kind, original.task_id, original.task_name, original.task_data)
        requests.append(request)
        if kind != 'duplicate':
            known_ids.append(task_id)
    return requests
