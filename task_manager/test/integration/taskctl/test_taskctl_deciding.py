"""taskctl and what decides what runs (issue 29): start with a priority, on conflict and
timeouts, reprioritize, why, and QUEUED tasks in `active`; a subprocess against a real node."""

import json
from pathlib import Path

from test_msgs.action import Fibonacci

from task_manager.testing.harness import RosHarness
from task_manager.testing.probe import TaskManagerProbe
from task_manager.testing.process import LaunchTaskManager, action_task, taskctl
from task_manager.testing.servers import ScriptedActionServer

TIMEOUT_SEC = 15.0


def robot(
    ros: RosHarness, launch: LaunchTaskManager, prefix: str
) -> tuple[TaskManagerProbe, dict[str, ScriptedActionServer]]:
    """A node with a drive and a dock that both hold `base`."""
    names = ('drive', 'dock')
    tasks = {name: action_task(name, f'{prefix}/{name}', resources=['base']) for name in names}
    servers = {
        name: ScriptedActionServer(ros.node, Fibonacci, entry['topic'])
        for name, entry in tasks.items()
    }
    return launch(tasks), servers


def test_why_names_the_drive_its_priority_and_base_for_a_refused_and_a_queued_task(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    drive = taskctl('start', 'drive', '{"order": 1}', '--id', 'drive-12', '--priority', '5',
                    '--no-wait')  # fmt: skip
    assert drive.returncode == 0, drive.stderr
    tm.wait_in_progress('drive-12')

    refused = taskctl('start', 'dock', '{"order": 1}', '--id', 'dock-3', '--priority', '1')
    queued = taskctl('start', 'dock', '{"order": 1}', '--id', 'dock-4', '--on-conflict', 'queue',
                     '--no-wait')  # fmt: skip
    tm.wait_active(lambda t: ('dock-4', 'QUEUED') in t)
    active = taskctl('active')
    active_json = taskctl('active', '--json')
    why_refused = taskctl('why', 'dock-3')
    why_queued = taskctl('why', 'dock-4')

    assert refused.returncode == 1
    assert (json.loads(refused.stdout)['status'], json.loads(refused.stdout)['error_code']) == (
        'ERROR',
        'preemption_refused',
    )
    reason = "refused: priority 1 is below drive-12's 5, which holds base"
    assert refused.stderr.strip().splitlines()[-1] == f'preemption_refused: {reason}'
    assert (queued.returncode, queued.stdout.strip()) == (0, 'dock-4')
    assert active.returncode == 0, active.stderr
    (row,) = [line for line in active.stdout.splitlines() if 'dock-4' in line]
    assert 'QUEUED #1' in row
    (dock,) = [
        d for d in map(json.loads, active_json.stdout.splitlines()) if d['task_id'] == 'dock-4'
    ]
    assert (dock['status'], dock['queue_position'], dock['priority']) == ('QUEUED', 1, 0)
    assert why_refused.returncode == 0, why_refused.stderr
    (line,) = why_refused.stdout.splitlines()
    assert line.split(maxsplit=2)[1:] == ['refused', reason]
    (line,) = why_queued.stdout.splitlines()
    assert line.split(maxsplit=2)[1:] == [
        'queued',
        'queued behind drive-12 (priority 5), which holds base',
    ]

    raised = taskctl('reprioritize', 'dock-4', 'ghost', '7')
    trail = taskctl('why', 'dock-4', '--json')

    assert raised.returncode == 1
    assert raised.stdout == 'dock-4  priority 7\n'
    assert 'ghost' in raised.stderr
    decisions = [json.loads(line) for line in trail.stdout.splitlines()]
    assert [d['decision'] for d in decisions] == ['queued', 'reprioritized']
    assert all(d['at'].endswith('+00:00') and d['reason'] for d in decisions)
    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    servers['dock'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    assert tm.wait_result_message('dock-4').task_status == 'DONE'


def test_start_with_a_timeout_ends_error_timeout_and_why_says_which(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    robot(ros, launch_task_manager, topic_prefix)

    timed_out = taskctl('start', 'drive', '{"order": 1}', '--id', 'slow', '--timeout', '0.5')
    why = taskctl('why', 'slow')
    unknown = taskctl('why', 'nobody')
    bad = taskctl('start', 'drive', '--on-conflict', 'wait', env={'COLUMNS': '200'})

    assert timed_out.returncode == 1
    printed = json.loads(timed_out.stdout)
    assert (printed['status'], printed['error_code']) == ('ERROR', 'timeout')
    assert 'timeout_sec' in timed_out.stderr
    assert why.stdout.split(maxsplit=2)[1] == 'timeout'
    assert unknown.returncode == 1
    assert "knows no task 'nobody'" in unknown.stderr
    assert bad.returncode == 2 and "'wait' is not one of preempt, queue, reject" in bad.stderr


def test_a_mission_is_started_with_its_options(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str, tmp_path: Path
) -> None:
    tm, servers = robot(ros, launch_task_manager, topic_prefix)
    taskctl('start', 'drive', '{"order": 1}', '--id', 'drive-1', '--priority', '9', '--no-wait')
    tm.wait_in_progress('drive-1')
    tour = tmp_path / 'tour.yaml'
    tour.write_text('- {task_name: dock, task_data: {order: 1}, task_id: m-dock}\n')

    refused = taskctl('mission', str(tour), '--id', 'tour', '--on-conflict', 'reject')

    assert refused.returncode == 1
    assert json.loads(refused.stdout)['error_code'] == 'resource_busy'
    assert 'drive-1 (priority 9), which holds base' in refused.stderr
    servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()


def test_a_timed_out_task_prints_its_servers_result_and_says_why_on_stderr(
    ros: RosHarness, launch_task_manager: LaunchTaskManager, topic_prefix: str
) -> None:
    robot(ros, launch_task_manager, topic_prefix)

    ended = taskctl('start', 'drive', '{"order": 1}', '--id', 'slow', '--timeout', '0.5')

    assert ended.returncode == 1
    printed = json.loads(ended.stdout)
    assert (printed['status'], printed['error_code']) == ('ERROR', 'timeout')
    assert printed['result'] == {'sequence': []}  # the server's, nothing added
    assert ended.stderr.strip().splitlines()[-1] == 'timeout: timed out: ran 0.5 s (timeout_sec)'
