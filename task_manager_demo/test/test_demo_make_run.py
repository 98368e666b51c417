"""`make run`: the robot, the Task Manager and the dashboard come up, run a task, stop on Ctrl-C;
with TOKENS, the gateway's roles and names hold.

The test gives `make run` a ROS_HOME of its own: nothing it does lands in the user's history.
"""

import contextlib
import os
import re
import signal
import sqlite3
import time
from pathlib import Path

import httpx
import psutil
import pytest
from prometheus_client.parser import text_string_to_metric_families

from task_manager.testing.gateway import wait_until
from task_manager.testing.harness import RosHarness
from task_manager.testing.probe import TaskManagerProbe
from task_manager_demo.testing import DemoProcess

REPO = Path(__file__).resolve().parents[2]
# Generous: `make run` installs first when an input of `make install` changed.
READY_TIMEOUT_SEC = 180.0
STOP_TIMEOUT_SEC = 30.0
CHILD_SCRIPTS = ('task-manager-demo-robot', 'task-manager', 'task-manager-web')


def script_name(process: psutil.Process) -> str:
    """The console script a process runs (`python .../bin/task-manager ...`), or ''."""
    try:
        return next((Path(arg).name for arg in process.cmdline()[1:2]), '')
    except psutil.Error:
        return ''


def still_running(processes: list[psutil.Process]) -> list[psutil.Process]:
    return [p for p in processes if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]


def history_file(ros_home: Path) -> Path:
    """The demo Task Manager's default history file on this test's ROS domain."""
    domain = os.environ['ROS_DOMAIN_ID']
    return ros_home / 'task_manager' / f'domain{domain}' / 'task_manager' / 'history.sqlite'


def users_history_files() -> dict[Path, int]:
    """The files of the repository's `.ros` that a `make run` on this domain would write: its
    history and the one of earlier versions, which it would take over.

    key: the file, value: when it last changed (ns).
    """
    folder = REPO / '.ros' / 'task_manager'
    paths = [*history_file(REPO / '.ros').parent.rglob('*'), *folder.glob('history.sqlite*')]
    return {path: path.stat().st_mtime_ns for path in paths if path.is_file()}


def task_names(history: Path) -> list[str]:
    """Every request stored in a history file, ended or not."""
    with contextlib.closing(sqlite3.connect(f'file:{history}?mode=ro', uri=True)) as db:
        return [name for (name,) in db.execute('SELECT task_name FROM tasks ORDER BY entry')]


@pytest.mark.ros
def test_make_run_serves_tasks_and_stops_cleanly_on_ctrl_c(ros: RosHarness, tmp_path: Path) -> None:
    users_files = users_history_files()
    # any free port for the dashboard: the machine may run a `make run` of its own
    command = ['make', '--no-print-directory', 'run', 'WEB_PORT=0', f'DEMO_ROS_HOME={tmp_path}']
    make = DemoProcess('make run', command, cwd=REPO)
    try:
        make.wait_for_line(r'^Ctrl-C stops', READY_TIMEOUT_SEC)
        assert f'task history: {history_file(tmp_path)} (ROS_HOME={tmp_path})' in make.output
        assert 'Task Manager ready' in make.output
        assert '/task_manager/active_tasks' in make.output
        descendants = psutil.Process(make.pid).children(recursive=True)
        assert sorted(script_name(p) for p in descendants if script_name(p) in CHILD_SCRIPTS) == [
            'task-manager',
            'task-manager-demo-robot',
            'task-manager-web',
        ]
        dashboard = re.search(r'dashboard: (http://\S+)', make.output)
        assert dashboard is not None, make.output
        page = httpx.get(dashboard[1], timeout=STOP_TIMEOUT_SEC)
        assert page.status_code == 200 and '<title>Task Manager</title>' in page.text

        probe = TaskManagerProbe(ros)
        probe.wait_until_connected()
        result = probe.run('navigation/navigate_to_pose', {'x': 0.3, 'y': 0.0})
        probe.destroy()
        assert (result.task_status, result.error_code) == ('DONE', ''), result

        make.signal_group(signal.SIGINT)
        # make waits for its job, then ends itself by the SIGINT it received.
        assert make.wait_exit(STOP_TIMEOUT_SEC) in (0, -signal.SIGINT)
    finally:
        if make.child.exit_code is None:
            make.stop()
    assert 'the robot and the Task Manager have stopped' in make.output, make.output
    assert still_running(descendants) == []
    # the test's own task only: the probe's warm-up leaves none, the user's history is untouched
    assert task_names(history_file(tmp_path)) == ['navigation/navigate_to_pose']
    assert users_history_files() == users_files


VIEWER_TOKEN = 'viewer-token-0123456789'
OPERATOR_TOKEN = 'operator-token-0123456789'
METRICS_TIMEOUT_SEC = 10.0


@pytest.mark.ros
def test_make_run_with_tokens_refuses_a_viewer_names_who_started_and_counts_it(
    tmp_path: Path,
) -> None:
    tokens = tmp_path / 'tokens'
    tokens.write_text(f'viewer {VIEWER_TOKEN} hall\noperator {OPERATOR_TOKEN} alice\n')
    command = ['make', '--no-print-directory', 'run', 'WEB_PORT=0', f'DEMO_ROS_HOME={tmp_path}',
               f'TOKENS={tokens}']  # fmt: skip
    make = DemoProcess('make run', command, cwd=REPO)
    try:
        make.wait_for_line(r'^Ctrl-C stops', READY_TIMEOUT_SEC)
        dashboard = re.search(r'dashboard: (http://[^/\s]+)', make.output)
        assert dashboard is not None, make.output
        assert VIEWER_TOKEN not in make.output and OPERATOR_TOKEN not in make.output
        web = httpx.Client(base_url=dashboard[1], timeout=READY_TIMEOUT_SEC)
        # the gateway's client discovers the Task Manager a moment after both are ready
        wait_until(lambda: web.get('/api/health').json()['connected'], 'gateway connected')
        start = {'task_name': 'navigation/navigate_to_pose', 'task_data': {'x': 0.2, 'y': 0.0}}

        refused = web.post('/api/tasks/start', json=start, headers=bearer(VIEWER_TOKEN))
        assert refused.status_code == 403, refused.text
        assert 'needs role operator; this token is viewer' in refused.text
        done = web.post('/api/tasks/start?wait=true', json=start, headers=bearer(OPERATOR_TOKEN))
        assert done.status_code == 200, done.text
        assert (done.json()['task']['status'], done.json()['task']['source']) == (
            'DONE',
            'WEB:alice',
        )
        # the gateway counts from the event stream, which may follow the answer by a moment
        assert wait_for_ended_count(web, 'navigation/navigate_to_pose', 'DONE') == 1.0

        make.signal_group(signal.SIGINT)
        assert make.wait_exit(STOP_TIMEOUT_SEC) in (0, -signal.SIGINT)
    finally:
        if make.child.exit_code is None:
            make.stop()
    # the viewer's start never reached the Task Manager
    assert task_names(history_file(tmp_path)) == ['navigation/navigate_to_pose']


def bearer(token: str) -> dict[str, str]:
    return {'Authorization': f'Bearer {token}'}


def wait_for_ended_count(web: httpx.Client, task_name: str, status: str) -> float:
    """The count of /metrics once it is not 0, or 0 after METRICS_TIMEOUT_SEC."""
    deadline = time.monotonic() + METRICS_TIMEOUT_SEC
    while True:
        metrics = web.get('/metrics', headers=bearer(VIEWER_TOKEN))
        assert metrics.status_code == 200, metrics.text
        count = ended_count(metrics.text, task_name, status)
        if count or time.monotonic() > deadline:
            return count


def ended_count(exposition: str, task_name: str, status: str) -> float:
    """task_manager_tasks_ended_total{task_name, status}, read by prometheus_client's parser."""
    for family in text_string_to_metric_families(exposition):
        for sample in family.samples:
            labels = sample.labels
            if sample.name == 'task_manager_tasks_ended_total' and labels == {
                'task_name': task_name,
                'status': status,
            }:
                return sample.value
    return 0.0
