"""prepare_ros_process: message type supports load without rosidl's code generator, which
stays available on demand; end_within: a program's end is bounded. Each case runs in a fresh
interpreter (the setup acts on sys.modules, once per process; end_within may exit it)."""

import os
import subprocess
import sys

LOAD_A_TYPE_SUPPORT = """
import sys
{setup}
from std_srvs.srv import Trigger
Trigger.__class__.__import_type_support__()
print('lark' in sys.modules)
"""


def _lark_loaded_by_a_type_support(setup: str) -> bool:
    script = LOAD_A_TYPE_SUPPORT.format(setup=setup)
    output = subprocess.run(
        [sys.executable, '-c', script], capture_output=True, text=True, check=True, timeout=60
    ).stdout
    return output.split()[-1] == 'True'


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
import sys, time
from task_manager import process_setup
process_setup.END_TIMEOUT_SEC = 0.5

def wedged_in_the_middleware():
    time.sleep(60)  # in C, as a deadlocked Fast DDS call is

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


def test_with_faulthandler_on_the_stuck_thread_stack_is_printed_too() -> None:
    ended = _end_within('release = wedged_in_the_middleware', '-X', 'faulthandler')
    assert ended.returncode == 7
    assert 'in wedged_in_the_middleware' in ended.stderr, ended.stderr
