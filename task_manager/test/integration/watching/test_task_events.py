"""/task_manager/task_events and /task_manager/get_task_states over real DDS."""

import contextlib
import itertools
import json
import math
import threading
import time
from typing import Any

from rclpy.client import Client
from task_manager_msgs.msg import TaskEvent, TaskState
from task_manager_msgs.srv import GetTaskStates
from test_msgs.action import Fibonacci
from test_msgs.srv import BasicTypes

from task_manager.core.names import TASK_EVENT_BATCHES_TOPIC, TASK_EVENTS_TOPIC
from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.testing.harness import (
    RosHarness,
    TopicRecorder,
    WaitTimeoutError,
    wait_for_future,
)
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import LaunchTaskManager, action_task, service_task
from task_manager.testing.servers import ScriptedActionServer, ScriptedGoal, ScriptedService

TIMEOUT_SEC = 15.0
FAST_FEEDBACK_PERIOD_SEC = 0.01  # 100 Hz
FAST_FEEDBACK_COUNT = 150  # 1.5 s of it
RATE_HZ = 10.0
FEEDBACK_REPEAT_SEC = 0.2


def _seconds(stamp: Any) -> float:
    return float(stamp.sec + stamp.nanosec * 1e-9)


def _until_ended(events: TopicRecorder, task_id: str) -> list[TaskEvent]:
    """Every event of `task_id`, once its ENDED event has arrived."""
    return events.wait_until(
        lambda msgs: (
            mine
            if (mine := [m for m in msgs if m.task.task_id == task_id])
            and mine[-1].event == TaskEvent.ENDED
            else None
        ),
        TIMEOUT_SEC,
        f'the events of {task_id} up to ENDED',
    )


def _feedback_until_seen(goal: ScriptedGoal, feedback: Any, events: TopicRecorder) -> None:
    """Publish `feedback` until its event arrives (feedback is volatile, as in ROS)."""
    deadline = time.monotonic() + TIMEOUT_SEC
    while time.monotonic() < deadline:
        goal.publish_feedback(feedback)
        with contextlib.suppress(WaitTimeoutError):
            events.wait_until(
                lambda msgs: any(m.event == TaskEvent.FEEDBACK for m in msgs),
                FEEDBACK_REPEAT_SEC,
                'feedback',
            )
            return
    raise WaitTimeoutError(f'no FEEDBACK event within {TIMEOUT_SEC} s')


def _progress(event: TaskEvent) -> tuple[int, list[tuple[str, str, bool]]] | None:
    """A mission's feedback as (current_index, [(subtask id, status, skipped)])."""
    if event.event != TaskEvent.FEEDBACK or event.task.task_name != 'system/mission':
        return None
    progress = json.loads(event.task.feedback)
    subtasks = [(r['task_id'], r['task_status'], r['skipped']) for r in progress['subtasks']]
    return progress['current_index'], subtasks


def _launch(
    ros: RosHarness, launch: LaunchTaskManager, prefix: str, **parameters: Any
) -> tuple[ScriptedActionServer, TaskManagerProbe]:
    server = ScriptedActionServer(ros.node, Fibonacci, f'{prefix}/fib')
    tm = launch({'fib': action_task('fib', f'{prefix}/fib', reentrant=True)}, **parameters)
    return server, tm


def test_a_task_has_received_started_feedback_and_ended_events_in_order(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server, tm = _launch(ros, launch_task_manager, topic_prefix)
    events = tm.record_events()

    handle = tm.send('fib', {'order': 3}, task_id='t1', source='CLOUD')
    goal = server.wait_for_goals(1, TIMEOUT_SEC)[0]
    _feedback_until_seen(goal, Fibonacci.Feedback(sequence=[0, 1]), events)
    goal.succeed(Fibonacci.Result(sequence=[0, 1, 1]))
    tm.result_of(handle)
    mine = _until_ended(events, 't1')

    assert [m.event for m in mine] == ['RECEIVED', 'STARTED', 'FEEDBACK', 'ENDED']
    stamps = [_seconds(m.stamp) for m in mine]
    assert stamps == sorted(stamps)
    received, started, feedback, ended = (m.task for m in mine)
    assert (received.task_status, started.task_status) == ('RECEIVED', 'IN_PROGRESS')
    assert (received.source, received.task_name, received.mission_id) == ('CLOUD', 'fib', '')
    assert json.loads(feedback.feedback) == {'sequence': [0, 1]}
    assert (ended.task_status, ended.error_code) == ('DONE', '')
    assert json.loads(ended.task_result) == {'sequence': [0, 1, 1]}
    assert 0 < _seconds(ended.received) <= _seconds(ended.started) <= _seconds(ended.ended)
    assert _seconds(received.started) == _seconds(received.ended) == 0
    assert received.task_result == started.task_result == ''


def test_a_refused_task_is_received_and_ended_without_starting(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    _, tm = _launch(ros, launch_task_manager, topic_prefix)
    events = tm.record_events()

    tm.run('no/such', {}, task_id='t2')
    mine = _until_ended(events, 't2')

    assert [m.event for m in mine] == ['RECEIVED', 'ENDED']
    assert (mine[-1].task.task_status, mine[-1].task.error_code) == ('ERROR', 'unknown_task')
    assert 'declared tasks: fib' in json.loads(mine[-1].task.task_result)['error']
    assert _seconds(mine[-1].task.started) == 0


def test_a_system_task_s_feedback_at_its_start_comes_after_its_started_event(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    _, tm = _launch(ros, launch_task_manager, topic_prefix)
    events = tm.record_events()

    tm.run('system/wait', {'duration': 0.2}, task_id='w1')  # its feedback made as it starts
    mine = _until_ended(events, 'w1')

    assert [m.event for m in mine] == ['RECEIVED', 'STARTED', 'FEEDBACK', 'ENDED']
    assert mine[2].task.task_status == 'IN_PROGRESS'
    assert json.loads(mine[2].task.feedback)['remaining_time'] > 0


def test_fast_feedback_is_rate_limited_and_the_latest_comes_before_the_end(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server, tm = _launch(ros, launch_task_manager, topic_prefix, feedback_rate_hz=RATE_HZ)
    events = tm.record_events()
    handle = tm.send('fib', {'order': 3}, task_id='fast')
    goal = server.wait_for_goals(1, TIMEOUT_SEC)[0]
    sent = [0]
    all_sent = threading.Event()

    def publish() -> None:  # on the harness' executor, at 100 Hz
        if sent[0] < FAST_FEEDBACK_COUNT:
            sent[0] += 1
            goal.goal_handle.publish_feedback(Fibonacci.Feedback(sequence=[sent[0]]))
        else:
            all_sent.set()

    timer = ros.on_executor(lambda: ros.node.create_timer(FAST_FEEDBACK_PERIOD_SEC, publish))
    try:
        assert all_sent.wait(TIMEOUT_SEC)
    finally:
        ros.on_executor(lambda: ros.node.destroy_timer(timer))
    goal.succeed(Fibonacci.Result(sequence=[1]))
    tm.result_of(handle)
    mine = _until_ended(events, 'fast')

    feedback = [m for m in mine if m.event == TaskEvent.FEEDBACK]
    span = _seconds(feedback[-1].stamp) - _seconds(feedback[0].stamp)
    # at most one per interval (a little slack for timer jitter), yet some every interval
    assert len(feedback) <= span * RATE_HZ + 2, len(feedback)
    assert len(feedback) >= 5
    gaps = [_seconds(b.stamp) - _seconds(a.stamp) for a, b in itertools.pairwise(feedback)]
    # the last one may come early: a feedback held for its slot goes out as the task ends
    assert min(gaps[:-1]) >= 0.8 / RATE_HZ, gaps
    # latest wins: the last update the server sent is the last event before ENDED
    assert mine[-2].event == TaskEvent.FEEDBACK
    assert json.loads(mine[-2].task.feedback) == {'sequence': [FAST_FEEDBACK_COUNT]}


def test_a_mission_publishes_its_progress_as_feedback(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server_goals, tm = _launch(ros, launch_task_manager, topic_prefix)
    events = tm.record_events()
    subtasks = [
        {'task_id': 's1', 'task_name': 'fib', 'task_data': '{"order": 1}'},
        {'task_id': 's2', 'task_name': 'nope', 'task_data': '{}', 'allow_skipping': True},
        {'task_id': 's3', 'task_name': 'fib', 'task_data': '{"order": 2}'},
    ]
    handle = tm.send('system/mission', {'subtasks': subtasks}, task_id='m1')
    server_goals.wait_for_goals(1, TIMEOUT_SEC)[0].succeed(Fibonacci.Result(sequence=[1]))
    third = server_goals.wait_for_goals(2, TIMEOUT_SEC)[1]
    # while s3 runs, its progress is the latest, so it goes out (changes within one rate
    # interval are coalesced: the latest wins)
    s3_running = [('s1', 'DONE', False), ('s2', 'ERROR', True), ('s3', 'IN_PROGRESS', False)]
    events.wait_until(
        lambda msgs: any(_progress(m) == (2, s3_running) for m in msgs), TIMEOUT_SEC, 's3 running'
    )
    third.succeed(Fibonacci.Result(sequence=[2]))
    tm.result_of(handle)
    mine = _until_ended(events, 'm1')

    rows = [row for m in mine if (row := _progress(m)) is not None]
    first = [('s1', 'IN_PROGRESS', False), ('s2', 'RECEIVED', False), ('s3', 'RECEIVED', False)]
    last = [('s1', 'DONE', False), ('s2', 'ERROR', True), ('s3', 'DONE', False)]
    assert rows[0] == (0, first)
    assert rows[-1] == (-1, last)
    assert (2, s3_running) in rows
    indexes = [index for index, _ in rows[:-1]]
    assert indexes == sorted(indexes)
    subtask_events = _until_ended(events, 's1')
    assert {m.task.mission_id for m in subtask_events} == {'m1'}


def test_a_late_client_gets_the_state_of_every_active_task(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    server, tm = _launch(ros, launch_task_manager, topic_prefix)
    handle = tm.send('fib', {'order': 3}, task_id='running', source='UI')
    goal = server.wait_for_goals(1, TIMEOUT_SEC)[0]
    _feedback_until_seen(goal, Fibonacci.Feedback(sequence=[7]), tm.record_events())
    client: Client[GetTaskStates.Request, GetTaskStates.Response] = ros.node.create_client(
        GetTaskStates, '/task_manager/get_task_states'
    )
    assert wait_until_ready(client.service_is_ready, TIMEOUT_SEC)

    def states(*task_ids: str) -> list[TaskState]:
        request = GetTaskStates.Request(task_ids=list(task_ids))
        return list(wait_for_future(client.call_async(request), TIMEOUT_SEC, 'states').tasks)

    tm.wait_in_progress('running')
    active = states()
    goal.succeed(Fibonacci.Result(sequence=[7]))
    tm.result_of(handle)
    ended = states('running', 'unknown-id')
    ros.node.destroy_client(client)

    assert [(s.task_id, s.task_status, s.source) for s in active] == [
        ('running', 'IN_PROGRESS', 'UI')
    ]
    assert _seconds(active[0].started) > 0 and _seconds(active[0].ended) == 0
    assert json.loads(active[0].feedback) == {'sequence': [7]}
    assert [(s.task_id, s.task_status) for s in ended] == [('running', 'DONE')]
    assert json.loads(ended[0].task_result) == {'sequence': [7]}


def test_the_event_stream_can_be_switched_off(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    _launch(ros, launch_task_manager, topic_prefix, publish_task_events=False)

    publishers = ros.node.get_publishers_info_by_topic(TASK_EVENTS_TOPIC)
    batch_publishers = ros.node.get_publishers_info_by_topic(TASK_EVENT_BATCHES_TOPIC)

    assert (publishers, batch_publishers) == ([], [])


def test_a_result_json_cannot_hold_is_converted_and_the_node_goes_on(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    ScriptedService(
        ros.node,
        BasicTypes,
        f'{topic_prefix}/basic',
        on_call=lambda call: call.respond(float64_value=math.nan, float32_value=math.inf),
    )
    tm = launch_task_manager(
        {'basic': service_task('basic', f'{topic_prefix}/basic', 'test_msgs/srv/BasicTypes')}
    )
    events = tm.record_events()

    result = tm.run('basic', {'bool_value': True}, task_id='nan')
    ended = _until_ended(events, 'nan')[-1].task

    assert (result.task_status, result.error_code) == ('DONE', '')
    for text in (result.task_result, ended.task_result, tm.wait_result_message('nan').task_result):
        converted = json.loads(text)
        assert (converted['float64_value'], converted['float32_value']) == (None, None)
    assert tm.run('basic', {'bool_value': True}).task_status == 'DONE'  # still serving
