"""lower_cpu_priority: every thread of the process, those running and those it starts later,
at the nice value asked at least; the `--nice` values a gateway accepts. Each case runs in a
fresh interpreter, since a process cannot take its priority back."""

import argparse
import json
import subprocess
import sys

import pytest

from task_manager.cpu_priority import MAX_NICENESS, niceness

THREADS_BEFORE_AND_AFTER = """
import json, os, threading
from task_manager.cpu_priority import lower_cpu_priority

def nice_of(thread):
    return os.getpriority(os.PRIO_PROCESS, thread.native_id)

release = threading.Event()
before = threading.Thread(target=release.wait)
before.start()
first = lower_cpu_priority({first})
after = threading.Thread(target=release.wait)
after.start()
second = lower_cpu_priority({second})
threads = [threading.main_thread(), before, after]
print(json.dumps([first, second, *(nice_of(thread) for thread in threads)]))
release.set()
"""


def _nice_values(first: int, second: int, start_at: int = 0) -> list[int]:
    script = THREADS_BEFORE_AND_AFTER.format(first=first, second=second)
    command = ['nice', '-n', str(start_at), sys.executable, '-c', script]
    output = subprocess.run(command, capture_output=True, text=True, check=True, timeout=60)
    return list(json.loads(output.stdout))


def test_every_thread_running_and_started_later_takes_the_nice_value() -> None:
    assert _nice_values(10, 10) == [10, 10, 10, 10, 10]


def test_a_lower_value_asked_later_keeps_the_higher_one() -> None:
    assert _nice_values(12, 5) == [12, 12, 12, 12, 12]


def test_a_process_started_nicer_stays_as_nice() -> None:
    assert _nice_values(10, 0, start_at=15) == [15, 15, 15, 15, 15]


def test_zero_keeps_the_priority_it_was_started_with() -> None:
    assert _nice_values(0, 0) == [0, 0, 0, 0, 0]


@pytest.mark.parametrize('text', ['0', '10', str(MAX_NICENESS)])
def test_nice_values_a_gateway_accepts(text: str) -> None:
    assert niceness(text) == int(text)


@pytest.mark.parametrize(
    ('text', 'message'),
    [('-1', 'not between 0 and 19'), ('20', 'not between 0 and 19'), ('ten', 'not a whole')],
)
def test_nice_values_a_gateway_refuses(text: str, message: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError, match=message):
        niceness(text)
