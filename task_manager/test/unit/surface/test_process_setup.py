"""prepare_ros_process: numpy loads without a BLAS thread pool, message type supports without
rosidl's code generator, which stays available on demand; end_within: a program's end is
bounded. Each case runs in a fresh interpreter (the setup acts on sys.modules and the
environment, once per process; end_within may exit it). stop_when_unheard: a program stops
once, when its client no longer hears the node."""

import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from task_manager.process_setup import BLAS_THREADS_VARIABLE, stop_when_unheard

LOAD_A_TYPE_SUPPORT = """
import sys
{setup}
from std_srvs.srv import Trigger
Trigger.__class__.__import_type_support__()
print('lark' in sys.modules)
"""


def _last_word(script: str, environment: dict[str, str] | None = None) -> str:
    """The last word `script` prints, run in a fresh interpreter."""
    output = subprocess.run(
        [sys.executable, '-c', script],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
        env=environment,
    ).stdout
    return output.split()[-1]


def _lark_loaded_by_a_type_support(setup: str) -> bool:
    return _last_word(LOAD_A_TYPE_SUPPORT.format(setup=setup)) == 'True'


def test_a_type_support_loads_without_the_code_generator() -> None:
    # rosidl's own package imports its generator (lark) with every type support...
    assert _lark_loaded_by_a_type_support('')
    # ...and not once the process is prepared
    assert not _lark_loaded_by_a_type_support(
        'from task_manager.process_setup import prepare_ros_process; prepare_ros_process()'
    )


def test_the_code_generator_is_still_there_when_asked_for() -> None:
    script = (
        'from task_manager.process_setup import load_type_supports_without_code_generator as f\n'
        'assert f()\n'
        'assert not f()\n'
        'from rosidl_generator_py import generate_py, import_type_support\n'
        'import rosidl_generator_py.generate_py_impl as impl\n'
        'assert generate_py is impl.generate_py and callable(import_type_support)\n'
    )
    subprocess.run([sys.executable, '-c', script], check=True, timeout=60)


END_WITH = """
import re, sys, time
from task_manager import process_setup
process_setup.END_TIMEOUT_SEC = 0.5
process_setup.LAST_RESORT_SEC = 0.5

def wedged_in_the_middleware():
    time.sleep(60)  # in C, as a deadlocked Fast DDS call is

def spinning_with_the_gil():
    # in C without letting go of the GIL, as rclpy's destroy_node in a Fast DDS spin is:
    # backtracking through about 10**12 ways to split the a's, none followed by a b
    re.fullmatch('(a|aa)+b', 'a' * 60)

{release}
process_setup.end_within(release, 'a-program', 7)
print('returned')
"""


def _end_within(release: str, *options: str) -> subprocess.CompletedProcess[str]:
    """`release` given to end_within in a fresh interpreter (faulthandler off, which the test
    run turns on for the processes it starts, unless `options` turn it on)."""
    env = {name: value for name, value in os.environ.items() if name != 'PYTHONFAULTHANDLER'}
    return subprocess.run(
        [sys.executable, *options, '-c', END_WITH.format(release=release)],
        capture_output=True,
        text=True,
        timeout=60,
        env=env,
    )


def test_a_release_that_ends_in_time_returns_and_says_nothing() -> None:
    ended = _end_within('def release(): pass')
    assert (ended.returncode, ended.stdout, ended.stderr) == (0, 'returned\n', '')


def test_an_error_of_the_release_is_raised_in_the_caller() -> None:
    ended = _end_within('def release(): raise ValueError("bad")')
    assert ended.returncode == 1 and 'returned' not in ended.stdout
    assert ended.stderr.strip().splitlines()[-1] == 'ValueError: bad'


def test_a_release_stuck_in_the_middleware_ends_the_process_with_the_code_and_one_line() -> None:
    ended = _end_within('release = wedged_in_the_middleware')
    assert ended.returncode == 7 and 'returned' not in ended.stdout
    assert ended.stderr == (
        'a-program: the ROS middleware did not shut down within 0.5 s; exiting anyway\n'
    )


def test_a_release_stuck_holding_the_gil_still_ends_the_process() -> None:
    started = time.monotonic()
    ended = _end_within('release = spinning_with_the_gil')
    assert ended.returncode == 1 and 'returned' not in ended.stdout
    assert ended.stderr.startswith('Timeout (0:00:01)!'), ended.stderr
    assert 'in spinning_with_the_gil' in ended.stderr
    assert time.monotonic() - started < 30


def test_with_faulthandler_on_the_stuck_thread_stack_is_printed_too() -> None:
    ended = _end_within('release = wedged_in_the_middleware', '-X', 'faulthandler')
    assert ended.returncode == 7
    assert 'in wedged_in_the_middleware' in ended.stderr, ended.stderr


COUNT_BLAS_THREADS = """
import os
{setup}
before = len(os.listdir('/proc/self/task'))
import numpy
print(len(os.listdir('/proc/self/task')) - before)
"""


def _without_blas_setting() -> dict[str, str]:
    """The environment without OPENBLAS_NUM_THREADS (the tests' conftest sets it)."""
    return {k: v for k, v in os.environ.items() if k != BLAS_THREADS_VARIABLE}


def _threads_numpy_starts(setup: str, environment: dict[str, str]) -> int:
    return int(_last_word(COUNT_BLAS_THREADS.format(setup=setup), environment))


def _asked_for_two() -> dict[str, str]:
    """The environment of a caller that asks OpenBLAS for two threads (it starts one beside
    the caller's, on a machine of two cores or more: it starts no more than the cores)."""
    return {**_without_blas_setting(), BLAS_THREADS_VARIABLE: '2'}


def test_a_prepared_process_loads_numpy_without_a_blas_thread_pool_unless_asked() -> None:
    prepare = 'from task_manager.process_setup import prepare_ros_process; prepare_ros_process()'
    # the count sees OpenBLAS's pool
    assert _threads_numpy_starts('', _asked_for_two()) == 1
    # a prepared process starts none, and one whose caller asked for threads gets them
    assert _threads_numpy_starts(prepare, _without_blas_setting()) == 0
    assert _threads_numpy_starts(prepare, _asked_for_two()) == 1


# the simulated robot serves on at `--help`: its console script goes the same way (run_program)
PROGRAMS_THAT_EXIT_AT_HELP = (
    'task-manager',
    'taskctl',
    'task-manager-web',
    'task-manager-mqtt',
    'task-manager-vda5050',
)
THREADS_AT_HELP = """
import atexit, os, sys
from importlib.metadata import entry_points
atexit.register(lambda: print('threads', len(os.listdir('/proc/self/task'))))
sys.argv = ['{script}', '--help']
entry_points(group='console_scripts')['{script}'].load()()
"""


def _threads_at_help(script: str, environment: dict[str, str], cwd: Path) -> int:
    run = subprocess.run(
        [sys.executable, '-c', THREADS_AT_HELP.format(script=script)],
        capture_output=True,
        text=True,
        timeout=60,
        env=environment,
        cwd=cwd,  # not the repository's root, whose folders would shadow the packages
    )
    # `task-manager --help` ends in one line (its parameters name no tasks), the others exit 0
    assert run.stdout.split()[-2:-1] == ['threads'], run.stderr
    return int(run.stdout.split()[-1])


def test_the_programs_console_scripts_prepare_before_numpy_loads(tmp_path: Path) -> None:
    """Each program's console script, as a user starts it: numpy (loaded by rclpy) starts no
    BLAS thread pool, which a caller asking for two threads shows it would otherwise."""
    for script in PROGRAMS_THAT_EXIT_AT_HELP:
        unset = _threads_at_help(script, _without_blas_setting(), tmp_path)
        assert _threads_at_help(script, _asked_for_two(), tmp_path) == unset + 1, script


class UnheardClient:
    """Stands in for a TaskManagerClient: keeps who asked to be told the node is unheard."""

    def __init__(self) -> None:
        self.told: list[Callable[[float], None]] = []

    def on_node_unheard(self, callback: Callable[[float], None]) -> Callable[[], None]:
        self.told.append(callback)
        return lambda: None


def test_a_program_whose_client_no_longer_hears_the_node_stops_once() -> None:
    client, stops = UnheardClient(), []
    unheard = stop_when_unheard(client, lambda: stops.append('stop'))
    assert not unheard.is_set() and not stops

    for tell in client.told * 2:  # told twice (two hold-ups): one stop
        tell(5.2)

    assert unheard.is_set() and stops == ['stop']


SIGNALS_TWICE = """
import os, signal, sys, threading, time
from task_manager import process_setup
process_setup.block_stop_signals()
stopping = threading.Event()
process_setup.on_stop_signal(stopping.set, 'a-program')
os.kill(os.getpid(), signal.SIGINT)
assert stopping.wait(10)
print('stopping', flush=True)
os.kill(os.getpid(), signal.SIGTERM)
time.sleep(30)  # an end that takes long: the second signal does not wait for it
"""


def test_a_second_stop_signal_ends_the_process_at_once_with_one_line() -> None:
    started = time.monotonic()
    ended = subprocess.run(
        [sys.executable, '-c', SIGNALS_TWICE], capture_output=True, text=True, timeout=60
    )
    assert (ended.returncode, ended.stdout) == (1, 'stopping\n')
    assert ended.stderr == 'a-program: a second signal: exiting at once\n'
    assert time.monotonic() - started < 20


INTERRUPTED_WHILE_WAITING = """
import queue, signal, threading
from task_manager.process_setup import INTERRUPT_SIGNAL, MainThreadInterrupt
ROUNDS = 100
asked = threading.Event()
interrupts = []
def interrupt():  # each round as soon as asked: as the main thread goes to block in its wait
    for _ in range(ROUNDS):
        asked.wait()
        asked.clear()
        interrupts[-1]()
threading.Thread(target=interrupt, daemon=True).start()
interrupted = 0
for _ in range(ROUNDS):
    interrupts.append(MainThreadInterrupt())
    asked.set()
    try:
        queue.SimpleQueue().get()  # no timeout, as taskctl following results
    except KeyboardInterrupt:
        interrupted += 1
print('interrupted', interrupted, flush=True)
signal.pthread_kill(threading.main_thread().ident, INTERRUPT_SIGNAL)  # as one sent again
threading.Event().wait(0.2)  # clean-up: the signal taken once already raises nothing more
print('clean-up not interrupted', interrupts[-1].taken, flush=True)
"""


def test_the_main_thread_waiting_with_no_timeout_is_interrupted_from_another_thread() -> None:
    """How taskctl ends when its client no longer hears the node: the signal comes as the main
    thread goes to block, the moment that loses a single one in some hours of this machine
    (the sending thread woken as the main thread lets go of the GIL); every round is
    interrupted, once, and a signal sent again after it was taken interrupts nothing."""
    ended = subprocess.run(
        [sys.executable, '-c', INTERRUPTED_WHILE_WAITING],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert ended.stdout == 'interrupted 100\nclean-up not interrupted True\n', ended.stderr
    assert ended.returncode == 0, ended.stderr


FIRST_SIGNAL_MISSED = """
import queue, signal, threading
from task_manager.process_setup import INTERRUPT_SIGNAL, MainThreadInterrupt
interrupt = MainThreadInterrupt()
taking = signal.getsignal(INTERRUPT_SIGNAL)
missed = []
def miss_the_first(signum, frame):  # as one that came just before the wait blocked
    if missed:
        taking(signum, frame)
    missed.append(signum)
signal.signal(INTERRUPT_SIGNAL, miss_the_first)
threading.Thread(target=interrupt, daemon=True).start()
try:
    queue.SimpleQueue().get()
except KeyboardInterrupt:
    print('interrupted after', len(missed), 'missed', flush=True)
"""


def test_a_signal_the_main_thread_missed_is_sent_again() -> None:
    """The lost signal made certain: the main thread acts on none but the second."""
    ended = subprocess.run(
        [sys.executable, '-c', FIRST_SIGNAL_MISSED], capture_output=True, text=True, timeout=30
    )
    assert (ended.returncode, ended.stdout) == (0, 'interrupted after 1 missed\n'), ended.stderr
