"""`task-manager-console` as users run it: one line and exit code 2 for what cannot be used at
the start; killed with SIGKILL in the middle of a burst of results and started again, every
result stored exactly once."""

import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from task_manager_mqtt.broker import free_port
from task_manager_mqtt.testing import BrokerProcess

from task_manager.testing.process import NodeProcess
from task_manager_console.main import READY_LINE
from task_manager_console.simulation.robot import SimulatedRobot
from task_manager_console.simulation.robot_loop import TIMEOUT_SEC
from task_manager_console.store.fleet_history import FleetHistory, HistoryFilter
from task_manager_console.testing import CONSOLE_USER, wait_until

CONSOLE = str(Path(sys.executable).with_name('task-manager-console'))
BURST = 4000
STORED_TIMEOUT_SEC = 60.0


def console(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [CONSOLE, *args], capture_output=True, text=True, timeout=TIMEOUT_SEC, check=False
    )


def test_a_database_unreachable_at_the_start_is_one_line_and_exit_code_2(
    tmp_path: Path,
) -> None:
    port = free_port()  # nothing listens there
    refused = console('--database', f'postgresql://console:hidden@127.0.0.1:{port}/fleet')
    assert refused.returncode == 2
    lines = refused.stderr.splitlines()
    assert len(lines) == 1, refused.stderr
    assert lines[0].startswith(
        f'task-manager-console: cannot open the fleet history at '
        f'postgresql+psycopg://console:***@127.0.0.1:{port}/fleet: connection failed'
    ), lines[0]
    assert 'hidden' not in refused.stderr

    (tmp_path / 'file').write_text('')
    unusable = console('--database', f'sqlite:///{tmp_path}/file/fleet.sqlite')
    assert unusable.returncode == 2
    assert unusable.stderr.count('\n') == 1
    assert 'cannot open the fleet history at sqlite:///' in unusable.stderr


def test_unusable_settings_are_one_line_and_exit_code_2(tmp_path: Path) -> None:
    bad_url = console('--broker-url', 'http://127.0.0.1', '--database', f'sqlite:///{tmp_path}/f')
    assert bad_url.returncode == 2
    assert bad_url.stderr.strip() == (
        "task-manager-console: broker URL 'http://127.0.0.1': expected "
        'mqtt://[user[:password]@]host[:port] or mqtts://...'
    )
    missing = console('--password-file', str(tmp_path / 'none'))
    assert missing.returncode == 2
    assert missing.stderr.startswith('task-manager-console: cannot read the password file')


@pytest.fixture
def start_console_process(
    broker: BrokerProcess, database_url: str, tmp_path: Path
) -> Iterator[Callable[[], NodeProcess]]:
    """Start `task-manager-console` on the test's broker (its own account, the password in a
    file) and database; it is ready once it follows the robots."""
    password_file = tmp_path / 'console_password'
    password_file.write_text(broker.passwords[CONSOLE_USER])
    password_file.chmod(0o600)
    processes: list[NodeProcess] = []

    def start() -> NodeProcess:
        command = [
            CONSOLE,
            '--broker-url',
            f'mqtt://{CONSOLE_USER}@127.0.0.1:{broker.port}',
            '--password-file',
            str(password_file),
            '--database',
            database_url,
            '--port',
            '0',  # its doors on a free port: another test's console may hold one
        ]
        process = NodeProcess(None, command=command)
        processes.append(process)
        process.wait_for_log(READY_LINE, TIMEOUT_SEC)
        return process

    yield start
    for process in processes:
        if process.process.poll() is None:
            process.stop()


def test_the_console_killed_in_a_burst_stores_every_result_once_when_restarted(
    broker: BrokerProcess,
    database_url: str,
    start_console_process: Callable[[], NodeProcess],
) -> None:
    first = start_console_process()
    history = FleetHistory.open(database_url)
    robot = SimulatedRobot(broker.port, 'robot1', broker.passwords['robot1'])
    try:
        robot.connect()
        sender = threading.Thread(target=robot.send_results, args=(BURST,))
        sender.start()
        wait_until(lambda: history.count() >= 200, TIMEOUT_SEC, 'the first results stored')
        assert first.kill() == -9  # SIGKILL: no clean stop, results in flight
        stored_before = history.count()
        sender.join(TIMEOUT_SEC)
        assert not sender.is_alive()  # the broker took every result of the burst
        assert stored_before < BURST, 'the burst had ended: nothing was in flight'

        start_console_process()
        wait_until(lambda: history.count() >= BURST, STORED_TIMEOUT_SEC, 'every result stored')
        stored = history.query(HistoryFilter(robot_id='robot1', limit=BURST))
        assert sorted(d['sequence'] for d in stored) == list(range(1, BURST + 1))
        assert history.count() == BURST
    finally:
        robot.close()
        history.close()
