"""Two Task Managers on one machine: one parameters file, two ROS domains, one ROS_HOME.

Each keeps its task history in its own default file, so both serve; the first to start takes
the one default file of the versions before; two that name the same file (history_path) still
cannot share it.
"""

import json
import time
from pathlib import Path

from task_manager.core.history.store import TaskHistory
from task_manager.core.status import TaskStatus
from task_manager.core.task import TaskRecord
from task_manager.core.task_spec import InterfaceName, TaskKind, TaskSpec
from task_manager.testing.domains import HISTORY_PER_DOMAIN, run_domains
from task_manager.testing.process import NodeProcess, action_task, taskctl, write_params_file

START_TIMEOUT_SEC = 20.0
EXIT_TIMEOUT_SEC = 20.0
EXIT_CONFIGURATION_ERROR = 2
# three domains of this run's own, where no other test's node serves
*DOMAINS, OTHER_DOMAIN = run_domains(HISTORY_PER_DOMAIN)
WAIT = '{"duration": 0.01}'  # system/wait's goal: a task that needs no server


def _in_domain(domain: int, home: Path) -> dict[str, str]:
    return {'ROS_DOMAIN_ID': str(domain), 'ROS_HOME': str(home)}


def _history_file(home: Path, domain: int) -> Path:
    return home / 'task_manager' / f'domain{domain}' / 'task_manager' / 'history.sqlite'


def _history_of_before(home: Path) -> Path:
    """`$ROS_HOME/task_manager/history.sqlite` as an earlier version left it: one task."""
    path = home / 'task_manager' / 'history.sqlite'
    history = TaskHistory(str(path))
    spec = TaskSpec('math/fib', '/fib', InterfaceName('test_msgs', TaskKind.ACTION, 'Fibonacci'))
    now = time.time()  # recent: older than history_max_age_days would be pruned at start
    record = TaskRecord('from-before', spec, 'CLI', task_data='{}', received_at=now - 2)
    record.mark_started(now=now - 1)
    record.mark_ended(TaskStatus.DONE, {}, now=now)
    history.write(record)
    history.flush()
    history.close()
    return path


def test_one_parameters_file_in_two_domains_both_serve_each_with_its_own_history(
    tmp_path: Path,
) -> None:
    home = tmp_path / 'ros_home'
    tasks = {'tasks': ['fib'], 'fib': action_task('math/fib', '/fib')}
    params = write_params_file(tmp_path / 'params.yaml', tasks)  # no history_path: the default
    before = _history_of_before(home)
    serving: list[NodeProcess] = []
    refused: NodeProcess | None = None
    try:
        for domain in DOMAINS:  # one after the other: the first takes the file of before
            serving.append(NodeProcess(params, env=_in_domain(domain, home)))
            serving[-1].wait_for_log(r'Task Manager ready', START_TIMEOUT_SEC)
        runs = [
            taskctl(
                'start', 'system/wait', WAIT, '--id', f'wait-{domain}', env=_in_domain(domain, home)
            )
            for domain in DOMAINS
        ]
        histories = [taskctl('history', '--json', env=_in_domain(d, home)) for d in DOMAINS]
        # a third one that names the first one's file is refused, the first goes on
        shared = str(_history_file(home, DOMAINS[0]))
        refused = NodeProcess(
            write_params_file(tmp_path / 'shared.yaml', {**tasks, 'history_path': shared}),
            env=_in_domain(OTHER_DOMAIN, home),
        )
        refused_code = refused.wait_exit(EXIT_TIMEOUT_SEC)
        again = taskctl('start', 'system/wait', WAIT, env=_in_domain(DOMAINS[0], home))
    finally:
        codes = [node.stop() for node in serving]
        if refused is not None:
            refused.stop()

    for domain, node, run in zip(DOMAINS, serving, runs, strict=True):
        where = f'task history: {_history_file(home, domain)}'
        assert any(line.endswith(where) for line in node.log_lines), node.log_lines
        assert run.returncode == 0, run.stderr
        assert json.loads(run.stdout)['status'] == 'DONE'
    ids = [[json.loads(line)['task_id'] for line in h.stdout.splitlines()] for h in histories]
    assert ids == [[f'wait-{DOMAINS[0]}', 'from-before'], [f'wait-{DOMAINS[1]}']]
    moved = f'moved the task history of an earlier version from {before} to '
    assert any(moved in line for line in serving[0].log_lines), serving[0].log_lines
    assert not before.exists()
    assert refused_code == EXIT_CONFIGURATION_ERROR
    in_use = (
        f'cannot open the task history {shared}: it is in use by another running Task Manager '
        f'(pid {serving[0].process.pid})'
    )
    assert any(in_use in line for line in refused.log_lines), refused.log_lines
    assert again.returncode == 0, again.stderr
    assert codes == [0, 0]
