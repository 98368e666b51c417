"""Hypothesis against a running Task Manager with hostile numbers, sizes and repetitions: a
request's options and every system task's document (waits, confirmations, schedules, lists of
ids, missions). Afterwards the node is alive, every request was answered exactly once, no goal
runs on its server untracked, and the schedules can still be read (docs/security.md: bounds).
"""

import contextlib
import json
import math
from collections import Counter
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rclpy.client import Client
from task_manager_msgs.srv import GetSchedules, GetTaskStates
from test_msgs.action import Fibonacci

from task_manager.client import TaskManagerClient
from task_manager.core.bounds import IDS_MAX
from task_manager.core.names import GET_SCHEDULES_SERVICE, GET_TASK_STATES_SERVICE
from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.testing.harness import RosHarness, WaitTimeoutError, wait_for_future
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import LaunchTaskManager, action_task
from task_manager.testing.servers import ScriptedActionServer, ScriptedGoal

pytestmark = pytest.mark.ros
TIMEOUT_SEC = 15.0
# how long an accepted request may run before the test cancels it (a wait of a week, say)
LET_RUN_SEC = 0.3
HELD = 99  # a Fibonacci order the server holds until cancelled; others succeed at once

# the numbers a careless or hostile client sends: edges of every bound, and far beyond them
EXTREME_FLOATS = st.one_of(
    st.sampled_from(
        [0.0, -0.0, -1.0, 1e-300, 0.05, 0.1, 604_800.0, 604_800.001, 8e9, 1e10, 1e300, -1e300]
    ),
    st.floats(allow_nan=False, allow_infinity=False),
)
OPTION_FLOATS = EXTREME_FLOATS | st.sampled_from([math.inf, -math.inf, math.nan])
FLOAT32_MAX = 3.4028234e38
INT32 = st.sampled_from([-(2**31), -1, 0, 1, 2**31 - 1]) | st.integers(-(2**31), 2**31 - 1)
IDS = st.lists(st.sampled_from(['a', 'b', 'held', 'x' * 256]), max_size=5) | st.just(['a'] * 1000)


def _settings(max_examples: int) -> settings:
    # derandomized: the same examples on every run, so that CI is deterministic
    return settings(
        max_examples=max_examples,
        derandomize=True,
        deadline=None,
        suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    )


@st.composite
def system_requests(draw: st.DrawFn) -> tuple[str, dict[str, Any]]:
    """One system task with a hostile document."""
    kind = draw(st.sampled_from(['wait', 'confirm', 'schedule', 'ids', 'mission']))
    if kind == 'wait':
        duration = draw(EXTREME_FLOATS.filter(lambda d: abs(d) <= FLOAT32_MAX))
        return 'system/wait', {'duration': duration}
    if kind == 'confirm':
        return 'system/confirm', {'prompt': 'go?', 'timeout_sec': draw(EXTREME_FLOATS)}
    if kind == 'schedule':
        when = draw(st.sampled_from(['delay_sec', 'period_sec']))
        return 'system/schedule', {
            'schedule_id': 'hostile',
            'task_name': 'drive',
            'task_data': json.dumps({'order': 1}),
            when: draw(EXTREME_FLOATS),
            'misfire_grace_sec': draw(EXTREME_FLOATS),
            'max_runs': draw(st.sampled_from([0, 1, 2**32 - 1])),
        }
    if kind == 'ids':
        name = draw(st.sampled_from(['cancel_task', 'pause', 'resume', 'reprioritize']))
        field = 'cancelled_tasks' if name == 'cancel_task' else 'task_ids'
        document: dict[str, Any] = {field: draw(IDS)}
        if name == 'reprioritize':
            document['priority'] = draw(INT32)
        return f'system/{name}', document
    count = draw(st.sampled_from([1, 2, 1000, 1001]))
    subtasks = [{'task_name': 'system/wait', 'task_data': '{"duration": 0.0}'}] * count
    return 'system/mission', {'subtasks': subtasks}


class Accounting:
    """Every request sent, the answer it got, and the goals the server saw."""

    def __init__(self, tm: TaskManagerProbe, server: ScriptedActionServer) -> None:
        self.tm = tm
        self.server = server
        self.answered: list[str] = []
        self.numbers = iter(range(1_000_000))

    def send(self, handle: Any) -> Any:
        """The request's one answer: its result, or, if it runs on (a long wait), its result
        once cancelled."""
        result_future = handle.get_result_async()
        try:
            result = wait_for_future(result_future, LET_RUN_SEC, 'result').result
        except WaitTimeoutError:
            self.tm.cancel(handle)
            result = wait_for_future(result_future, TIMEOUT_SEC, 'result after cancel').result
        self.answered.append(result.task_id)
        return result

    def next_id(self) -> str:
        return f'hostile-{next(self.numbers)}'

    def unschedule(self) -> None:
        self.tm.run('system/unschedule', {'schedule_ids': ['hostile']}, task_id=self.next_id())

    def settle(self, ros: RosHarness) -> None:
        """The node is alive and every request was answered once; no goal runs untracked."""
        final_id = self.next_id()
        final = self.tm.run('drive', {'order': 1}, task_id=final_id)
        assert final.task_status == 'DONE'
        self.tm.wait_result_message(final_id)
        sent = Counter(self.answered)
        published = Counter(m.task_id for m in self.tm.results.snapshot() if m.task_id in sent)
        assert published == sent, 'a request was answered more or less than once'
        self.tm.wait_active(lambda tasks: tasks == [], 'no active task left')
        assert all(goal.ended.is_set() for goal in self.server.goals.items), 'a goal runs on'
        assert _schedule_ids(ros) == set()


def _schedule_ids(ros: RosHarness) -> set[str]:
    client: Client[GetSchedules.Request, GetSchedules.Response] = ros.node.create_client(
        GetSchedules, '/task_manager/get_schedules'
    )
    try:
        assert wait_until_ready(client.service_is_ready, TIMEOUT_SEC)
        answer = wait_for_future(client.call_async(GetSchedules.Request()), TIMEOUT_SEC, 'list')
        return {schedule.schedule_id for schedule in answer.schedules}
    finally:
        ros.node.destroy_client(client)


@pytest.fixture
def accounting(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> Iterator[Accounting]:
    def decide(goal: ScriptedGoal) -> None:
        if goal.request.order != HELD:
            goal.succeed()

    server = ScriptedActionServer(ros.node, Fibonacci, f'{topic_prefix}/drive', on_goal=decide)
    tm = launch_task_manager(
        {'drive': action_task('drive', f'{topic_prefix}/drive', reentrant=True)}
    )
    books = Accounting(tm, server)
    yield books
    books.settle(ros)


def test_hostile_options_get_one_answer_and_leave_no_goal_running(
    accounting: Accounting,
) -> None:
    @given(
        timeouts=st.fixed_dictionaries(
            {},
            optional={
                'timeout_sec': OPTION_FLOATS,
                'queue_timeout_sec': OPTION_FLOATS,
                'feedback_timeout_sec': OPTION_FLOATS,
            },
        ),
        priority=st.none() | INT32,
        on_conflict=st.sampled_from(['', 'queue', 'QUEUE ', 'reject', 'preempt', 'x' * 300]),
        held=st.booleans(),
    )
    @_settings(60)
    def one_request(
        timeouts: dict[str, float], priority: int | None, on_conflict: str, held: bool
    ) -> None:
        options: dict[str, Any] = {**timeouts, 'on_conflict': on_conflict}
        if priority is not None:
            options['priority'] = priority
        order = HELD if held else 1
        handle = accounting.tm.start(
            'drive', {'order': order}, task_id=accounting.next_id(), **options
        )
        result = accounting.send(handle)
        assert result.task_status in ('DONE', 'ERROR', 'CANCELED')
        if result.error_code == 'invalid_request':
            error = json.loads(result.task_result)['error']
            assert error.split(' ')[0] in (*timeouts, 'priority', 'on_conflict'), error

    one_request()


def test_hostile_system_task_documents_get_one_answer_and_the_node_serves_on(
    accounting: Accounting,
) -> None:
    @given(request=system_requests())
    @_settings(80)
    def one_request(request: tuple[str, dict[str, Any]]) -> None:
        task_name, document = request
        handle = accounting.tm.send(task_name, document, task_id=accounting.next_id())
        result = accounting.send(handle)
        assert result.task_status in ('DONE', 'ERROR', 'CANCELED')
        if task_name == 'system/schedule':
            accounting.unschedule()

    one_request()


@contextlib.contextmanager
def _asking(
    ros: RosHarness, service_type: Any, name: str, ids_field: str, read: Callable[[Any], Any]
) -> Iterator[Callable[[list[str]], list[Any]]]:
    """While the block runs, `ask(ids)`: a request of `service_type` to the node's service
    `name` with `ids` in its `ids_field`, and what `read` takes of the answer."""
    client: Client[Any, Any] = ros.node.create_client(service_type, name)
    try:
        assert wait_until_ready(client.service_is_ready, TIMEOUT_SEC)

        def ask(ids: list[str]) -> list[Any]:
            request = service_type.Request(**{ids_field: ids})
            return list(read(wait_for_future(client.call_async(request), TIMEOUT_SEC, name)))

        yield ask
    finally:
        ros.node.destroy_client(client)


def test_states_of_more_tasks_than_a_request_may_name_answer_the_first_ones(
    ros: RosHarness, accounting: Accounting
) -> None:
    """GetTaskStates with 1,001 ids (each one not active is a history query on the node's
    executor): the first 1,000 are answered, the rest left out, and the log says so; the
    client asks such a list in requests of 1,000."""
    accounting.tm.run('drive', {'order': 1}, task_id='known')
    asking = _asking(ros, GetTaskStates, GET_TASK_STATES_SERVICE, 'task_ids', lambda a: a.tasks)
    with asking as states:
        assert [s.task_id for s in states([*['unknown'] * IDS_MAX, 'known'])] == []
        assert [s.task_id for s in states([*['unknown'] * (IDS_MAX - 1), 'known'])] == ['known']
    process = accounting.tm.process  # type: ignore[attr-defined]
    process.wait_for_log(f'get_task_states asked for {IDS_MAX + 1} tasks', TIMEOUT_SEC)
    with TaskManagerClient('hostile_ids', timeout_sec=TIMEOUT_SEC) as tasks:
        asked = tasks.task_states([*['unknown'] * IDS_MAX, 'known'])
    assert [state.task_id for state in asked] == ['known']  # in two requests


def test_schedules_asked_by_more_ids_than_a_request_may_name_answer_the_first_ones(
    ros: RosHarness, accounting: Accounting
) -> None:
    """GetSchedules with 1,001 ids (each one asked is a schedule in the answer, however often
    it is named): the first 1,000 are answered, the rest left out, and the log says so; the
    client asks such a list in requests of 1,000."""
    schedule = {
        'schedule_id': 'kept',
        'task_name': 'drive',
        'task_data': json.dumps({'order': 1}),
        'delay_sec': 3600.0,
    }
    assert accounting.tm.run('system/schedule', schedule, task_id='keep').task_status == 'DONE'
    asking = _asking(
        ros, GetSchedules, GET_SCHEDULES_SERVICE, 'schedule_ids', lambda a: a.schedules
    )
    with asking as schedules:
        assert [i.schedule_id for i in schedules([*['unknown'] * IDS_MAX, 'kept'])] == []
        assert [i.schedule_id for i in schedules(['kept'] * (IDS_MAX + 1))] == ['kept'] * IDS_MAX
    process = accounting.tm.process  # type: ignore[attr-defined]
    process.wait_for_log(f'get_schedules asked for {IDS_MAX + 1} schedules', TIMEOUT_SEC)
    with TaskManagerClient('hostile_schedule_ids', timeout_sec=TIMEOUT_SEC) as scheduling:
        asked = scheduling.schedules([*['unknown'] * IDS_MAX, 'kept'])
    assert [info.schedule_id for info in asked] == ['kept']  # in two requests
    accounting.tm.run('system/unschedule', {'schedule_ids': ['kept']}, task_id='unkeep')
