"""A gateway yields the CPU to the robot: its process runs at a lower priority (a higher nice
value) than the Task Manager and the robot's own nodes, unless told otherwise (`--nice 0`).

The gateways (web, MQTT, VDA 5050) relay what the node decides; the node and the task servers
do the robot's work. On a robot's few cores every event of every task is handled by each
gateway beside the node, and at equal priority they take the cores in turns with it: a round
trip through the node measured 1.5-1.8 times its time alone with both gateways attached, a
burst of tasks half its rate (docs/benchmarks.md, issue 40). At nice 10 the kernel runs the node
first when both are ready, and the gateways catch up once it is idle: their messages wait in
their readers (a thousand deep each) meanwhile. No privilege is needed to lower one's own
priority; raising it again needs one, so a process started nicer keeps its nice value.
"""

import argparse
import os

GATEWAY_NICENESS = 10
"""A gateway's nice value unless told otherwise: the kernel's weight of a nice-10 thread is about
a tenth of a nice-0 one's, so a busy gateway slows the node's turns little."""
MAX_NICENESS = 19


def niceness(text: str) -> int:
    """An argparse type: a nice value from 0 (the caller's priority) to MAX_NICENESS."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a whole number') from None
    if not is_niceness(value):
        raise argparse.ArgumentTypeError(f'{value} is not between 0 and {MAX_NICENESS}')
    return value


def is_niceness(value: object) -> bool:
    """Whether `value` is a nice value a gateway takes: a whole number from 0 to MAX_NICENESS."""
    return type(value) is int and 0 <= value <= MAX_NICENESS


def add_nice_argument(parser: argparse.ArgumentParser, default: int | None) -> None:
    """`--nice N` on a gateway's command line; `default` None: not set unless given."""
    parser.add_argument(
        '--nice',
        type=niceness,
        help=f"run at this nice value, 0-{MAX_NICENESS}, to yield the CPU to the robot's nodes; "
        f'0 keeps the priority it was started with ({GATEWAY_NICENESS})',
        default=argparse.SUPPRESS if default is None else default,
    )


def lower_cpu_priority(nice: int) -> int:
    """Run every thread of this process, and those it starts, at nice value `nice` at least;
    the nice value of its first thread afterwards. On Linux a nice value is a thread's, and a
    new thread takes its creator's: this is called before rclpy, DDS or a server start theirs,
    and sets the few already running too."""
    for thread in thread_ids():
        current = os.getpriority(os.PRIO_PROCESS, thread)
        if nice > current:
            os.setpriority(os.PRIO_PROCESS, thread, nice)
    return os.getpriority(os.PRIO_PROCESS, 0)


def thread_ids(process: int | str = 'self') -> list[int]:
    """The thread ids of `process` (a pid; this one by default), from /proc; for this process
    where /proc is not there to list, [0]: the calling thread."""
    try:
        return [int(name) for name in os.listdir(f'/proc/{process}/task')]
    except OSError:
        if process != 'self':
            raise
        return [0]
