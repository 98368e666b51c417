"""Fixtures of every test tree: an isolated ROS domain per test run, an in-process ROS node."""

import faulthandler
import json
import math
import os
import resource
import signal

# numpy, which every ROS 2 Python process imports (rclpy's service_msgs), starts OpenBLAS's
# thread pool, one thread per core, as it loads: 0.11 s of CPU in each of the ~900 processes of
# a run that import rclpy (0.47 -> 0.36 s). Nothing here does linear algebra: one thread, for
# this process and every process a test starts.
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

# Tests stop the processes they start with SIGINT, as a terminal's Ctrl-C does. A suite started
# in the background by a non-interactive shell has SIGINT ignored, and every process it starts
# inherits that until it installs a handler of its own: a SIGINT sent before then vanishes (the
# demo robot, signalled within its first 0.25 s, then served on in 5 of 23 starts). Python
# installs its handler only where SIGINT was not ignored: put it back for this process and
# its children (a handler, unlike "ignored", is not inherited across exec).
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

# A process a test starts that dies of a fatal signal (a segmentation fault at exit was seen
# once in a taskctl, and NodeProcess.stop aborts a process that does not stop) prints the
# Python stack of each of its threads to its stderr (and no core file: see pytest_configure).
os.environ.setdefault('PYTHONFAULTHANDLER', '1')

# Keep this run's DDS traffic apart from other runs on the machine, and on it: each run claims a
# group of domains no other run holds (task_manager.testing.domains), each pytest-xdist worker
# (gw0 to gw3) one of its first four, tests that start nodes in domains of their own the rest.
# The workers inherit the controller's claim through the environment.
from task_manager.testing.domains import claim_run_domains, worker_domain

if 'TASK_MANAGER_TEST_DOMAIN' not in os.environ:
    os.environ['TASK_MANAGER_TEST_DOMAIN'] = str(claim_run_domains(os.getpid()))
os.environ['ROS_DOMAIN_ID'] = str(
    worker_domain(
        int(os.environ['TASK_MANAGER_TEST_DOMAIN']), os.environ.get('PYTEST_XDIST_WORKER', 'gw0')
    )
)
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
# ROS logs and the Task Manager's default history go inside the repository (git-ignored),
# never into the user's ~/.ros; one folder per process (pytest-xdist workers inherit the
# environment of the process that starts them, and two Task Managers cannot share a history).
os.environ['ROS_HOME'] = os.path.join(
    os.path.dirname(__file__), 'build', 'test-ros-home', str(os.getpid())
)

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TextIO

import pytest
import rclpy

from task_manager.process_setup import prepare_ros_process
from task_manager.testing.gateway import Robot, ScriptedRobot
from task_manager.testing.harness import RosHarness
from task_manager.testing.native_stacks import NativeStacks


def pytest_configure(config: pytest.Config) -> None:
    """As the Task Manager's own processes do: this one and every process a test starts; and
    none of them writes a core file."""
    prepare_ros_process()
    resource.setrlimit(resource.RLIMIT_CORE, (0, resource.getrlimit(resource.RLIMIT_CORE)[1]))


STUCK_GRACE_SEC = 30.0
"""How long after its timeout a test whose process cannot run Python ends that process."""
NATIVE_STACKS_BEFORE_SEC = 25.0
"""How long before that end the process's native stacks are written (py-spy takes 1-3 s, gdb up
to 10)."""
STUCK_FILE = 'stuck-test-stacks.txt'
_stuck: list[TextIO] = []  # the process's STUCK_FILE, open while it runs


def _stuck_path() -> Path:
    return Path(os.environ['ROS_HOME']) / STUCK_FILE


def _stuck_file() -> TextIO:
    """STUCK_FILE of this process (opened on first use)."""
    if not _stuck:
        path = _stuck_path()
        path.parent.mkdir(parents=True, exist_ok=True)
        _stuck.append(path.open('a', encoding='utf-8'))
    return _stuck[0]


_native_stacks = NativeStacks(_stuck_path())


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    """pytest-timeout ends a test past its timeout from a thread of Python, which cannot run
    while a call into C holds the GIL (rclpy destroying a node's DDS participant while Fast DDS
    3.2 spins: docs/faults-and-shutdown.md). faulthandler's watchdog, a thread of C, ends this
    test process STUCK_GRACE_SEC after the test's timeout, after every thread's stack: the run
    fails naming the test (pytest.ini: a crashed worker is not replaced) instead of hanging.
    The stacks go to STUCK_FILE in the process's ROS_HOME (its stderr is pytest's capture),
    after the threads' native stacks, where a lock cycle in C is read (testing.native_stacks)."""
    marker = item.get_closest_marker('timeout')
    timeout = float(marker.args[0] if marker and marker.args else item.config.getini('timeout'))
    if timeout > 0:
        faulthandler.dump_traceback_later(timeout + STUCK_GRACE_SEC, exit=True, file=_stuck_file())
        _native_stacks.arm(timeout + STUCK_GRACE_SEC - NATIVE_STACKS_BEFORE_SEC)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()
        if timeout > 0:
            _native_stacks.disarm()


@pytest.fixture(scope='session')
def ros_context() -> Iterator[None]:
    rclpy.init()
    yield
    rclpy.try_shutdown()


@pytest.fixture
def ros(ros_context: None, request: pytest.FixtureRequest) -> Iterator[RosHarness]:
    """An in-process node, spun in the background, for the test's clients and servers."""
    harness = RosHarness(f'test_{abs(hash(request.node.nodeid)) % 10**8}')
    yield harness
    harness.close()


@pytest.fixture
def start_robot(ros: RosHarness, tmp_path: Path) -> Iterator[Callable[[], Robot]]:
    """The gateways' tests: start a Task Manager serving `fib` and `instant` (see
    ScriptedRobot); callable again after `robot.process.stop()`."""
    robot = ScriptedRobot(ros, tmp_path)
    yield robot.start
    robot.close()


@pytest.fixture
def robot(start_robot: Callable[[], Robot]) -> Robot:
    return start_robot()


# The test files, slowest first, with their seconds in a run (`make test-durations` writes them):
# pytest-xdist shares out whole files in collection order (`--dist loadfile`, its reordering by
# number of tests turned off in pytest.ini), so the longest start first and the run does not end
# with one process on a long file while the others idle. A file not listed yet goes first: new
# files are mostly tests that start processes.
FILE_SECONDS = Path(__file__).parent / 'test-durations.json'


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        '--store-durations',
        action='store_true',
        help=f'write the seconds each test file took to {FILE_SECONDS.name}',
    )


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    seconds = json.loads(FILE_SECONDS.read_text()) if FILE_SECONDS.exists() else {}
    # stable: the order within each file is kept
    items.sort(key=lambda item: -seconds.get(_test_file(item.nodeid), math.inf))


def _test_file(nodeid: str) -> str:
    return nodeid.split('::', 1)[0]


_seconds_by_file: dict[str, float] = {}


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """Seconds of each file's setups, calls and teardowns (in the controller, every process's)."""
    name = _test_file(report.nodeid)
    _seconds_by_file[name] = _seconds_by_file.get(name, 0.0) + report.duration


def pytest_sessionfinish(session: pytest.Session) -> None:
    if not session.config.getoption('store_durations') or hasattr(session.config, 'workerinput'):
        return
    slowest_first = sorted(_seconds_by_file.items(), key=lambda pair: -pair[1])
    FILE_SECONDS.write_text(
        json.dumps({name: round(seconds, 1) for name, seconds in slowest_first}, indent=1) + '\n'
    )
