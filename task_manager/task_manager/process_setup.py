"""What each of the Task Manager's ROS 2 processes sets up before rclpy starts (no rclpy here).

`prepare_ros_process()` is called first thing by every program of ours that runs a ROS 2 node
(the Task Manager, taskctl, the gateways, the simulated robot); `run_program` calls it before
the program's module, and so rclpy, is imported, which is how their console scripts start them:

- numpy's OpenBLAS starts one thread (the caller's environment may ask for more). rclpy loads
  numpy (every service type imports it through `service_msgs`), and OpenBLAS starts a pool of
  one thread per core as it loads; each spins about 0.1 s before it sleeps: 0.12 s of CPU at
  each start on two cores, and a thread more for each further core, for linear algebra that no
  program of ours does;
- Fast DDS announces the process quickly (`discovery.use_quick_discovery`);
- message type supports load without rosidl's code generator. A generated message imports
  `rosidl_generator_py` for its type support the first time a node uses it, and that package's
  `__init__` also imports its code generator (lark, empy, rosidl_parser) to offer
  `generate_py`, which only a build of interfaces calls: about 25 ms of CPU in every process,
  a twentieth of a Task Manager's start. Here the package is registered without running its
  `__init__`: `import_type_support` is loaded at once, `generate_py` when it is first asked for.

`end_within()` is how each of them ends once its work is done: its ROS entities are destroyed
within a bound, or the process exits anyway (see there). A program that runs a node of the
default context takes SIGINT and SIGTERM itself (`block_stop_signals`, `on_stop_signal`) rather
than leaving them to rclpy, whose handler shuts the context down from a thread of its own while
the program's main thread goes on: an executor then fails on the context gone, or a node is
destroyed while the context ends under it.
"""

import faulthandler
import importlib
import importlib.util
import os
import signal
import sys
import threading
from collections.abc import Callable
from types import ModuleType
from typing import Any

from task_manager.discovery import use_quick_discovery

GENERATOR_PACKAGE = 'rosidl_generator_py'
END_TIMEOUT_SEC = 5.0
"""How long a program's ROS entities may take to be destroyed once its work is done (well under
a second when nothing goes wrong)."""
LAST_RESORT_SEC = 2.0
"""How long after END_TIMEOUT_SEC faulthandler's own thread ends a process whose threads cannot
run Python any more (see end_within)."""


BLAS_THREADS_VARIABLE = 'OPENBLAS_NUM_THREADS'
STOP_SIGNALS = frozenset({signal.SIGINT, signal.SIGTERM})
"""The signals that ask one of our ROS 2 programs to end cleanly (Ctrl-C, a service manager)."""
INTERRUPT_SIGNAL = signal.SIGUSR1
"""How MainThreadInterrupt reaches the main thread."""
INTERRUPT_AGAIN_SEC = 0.1
"""How often MainThreadInterrupt sends its signal again until the main thread has taken it."""
EXIT_START_AGAIN = 3
"""The exit code of a program of ours that a new process of it would mend, for its supervisor
(and the project's launchers) to start it again: the node whose middleware is stuck, a gateway
that no longer hears its Task Manager."""
EXIT_NODE_UNHEARD = EXIT_START_AGAIN
"""A gateway's exit code when it no longer hears its Task Manager (the client's
`on_node_unheard`)."""


def prepare_ros_process() -> None:
    """One BLAS thread, quick discovery and type supports without the code generator (see the
    module); the BLAS setting counts only before rclpy is first imported."""
    os.environ.setdefault(BLAS_THREADS_VARIABLE, '1')
    use_quick_discovery()
    load_type_supports_without_code_generator()


def run_program(module: str) -> Any:
    """Prepare the process, then import `module` and return what its `main()` returns: the
    console scripts' way in, so that the program's imports (rclpy among them) come after."""
    prepare_ros_process()
    return importlib.import_module(module).main()


def load_type_supports_without_code_generator() -> bool:
    """Register `rosidl_generator_py` with only what loading a type support needs; whether it
    did (not when the package is already imported, or missing)."""
    if GENERATOR_PACKAGE in sys.modules:
        return False
    spec = importlib.util.find_spec(GENERATOR_PACKAGE)
    if spec is None or spec.submodule_search_locations is None:
        return False
    package = importlib.util.module_from_spec(spec)
    sys.modules[GENERATOR_PACKAGE] = package
    try:
        loading = importlib.import_module(f'{GENERATOR_PACKAGE}.import_type_support_impl')
    except ImportError:
        del sys.modules[GENERATOR_PACKAGE]
        return False
    package.import_type_support = loading.import_type_support  # type: ignore[attr-defined]
    package.__all__ = ['import_type_support', 'generate_py']  # type: ignore[attr-defined]
    package.__getattr__ = _code_generator_on_demand(package)  # type: ignore[method-assign]
    return True


def _code_generator_on_demand(package: ModuleType) -> Any:
    def __getattr__(name: str) -> Any:  # noqa: N807 (PEP 562: the module's attribute hook)
        if name != 'generate_py':
            raise AttributeError(f'module {package.__name__!r} has no attribute {name!r}')
        generating = importlib.import_module(f'{package.__name__}.generate_py_impl')
        package.generate_py = generating.generate_py  # type: ignore[attr-defined]
        return generating.generate_py

    return __getattr__


def block_stop_signals() -> None:
    """Block STOP_SIGNALS in this thread and so in every thread it starts from now on; first
    thing in a program, before rclpy or DDS start a thread a signal could be delivered to."""
    signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)


def on_stop_signal(stop: Callable[[], object], program: str) -> None:
    """Call `stop` from a thread of its own when the first of STOP_SIGNALS comes (they must be
    blocked in every thread: block_stop_signals); a second one ends the process at once, with
    one line on stderr and exit code 1 (a second Ctrl-C: do not wait for the end)."""

    def wait() -> None:
        signal.sigwait(STOP_SIGNALS)
        stop()
        signal.sigwait(STOP_SIGNALS)
        print(f'{program}: a second signal: exiting at once', file=sys.stderr, flush=True)
        os._exit(1)

    threading.Thread(target=wait, name=f'{program}-signals', daemon=True).start()


class MainThreadInterrupt:
    """KeyboardInterrupt raised in the main thread from any thread, as Ctrl-C would raise it
    (taskctl's wait in progress ends so when its client no longer hears the node), and raised
    for sure: a signal sent to the main thread itself (INTERRUPT_SIGNAL), again every
    INTERRUPT_AGAIN_SEC until its handler has run.

    Once is not enough: a signal that comes while the main thread is about to block (it has let
    go of the GIL, its wait not started yet) trips Python's flag but wakes nothing, and a wait
    with no timeout (taskctl following results) then never runs the handler. The sending thread
    tends to run just then, woken as the main thread lets go of the GIL: 355 of 2,000 single
    signals were so lost in one hour of this machine (a loop that signals as the main thread
    goes to block), none of 2,000 in a quieter one. The handler raises only the first time: a
    signal sent again as it ran never interrupts what the main thread does next (its clean-up).
    A signal of its own, so that a user's Ctrl-C (SIGINT) keeps Python's handling.
    """

    def __init__(self) -> None:
        """In the main thread (it sets the signal's handler), before the signal is sent."""
        self._taken = threading.Event()
        self._sending = threading.Lock()
        self._sent = False
        signal.signal(INTERRUPT_SIGNAL, self._raise_once)

    @property
    def taken(self) -> bool:
        """Whether the main thread has raised the KeyboardInterrupt."""
        return self._taken.is_set()

    def __call__(self) -> None:
        """Interrupt the main thread (returns at once; once only: later calls do nothing)."""
        with self._sending:
            if self._sent:
                return
            self._sent = True
        main = threading.main_thread().ident or 0
        if _signal_thread(main):
            threading.Thread(
                target=self._send_again_until_taken,
                args=(main,),
                name='interrupt-main-thread',
                daemon=True,
            ).start()

    def _send_again_until_taken(self, main: int) -> None:
        while not self._taken.wait(INTERRUPT_AGAIN_SEC) and _signal_thread(main):
            pass

    def _raise_once(self, _signal: int, _frame: object) -> None:
        if self._taken.is_set():
            return
        self._taken.set()
        raise KeyboardInterrupt


def _signal_thread(thread: int) -> bool:
    """Send INTERRUPT_SIGNAL to `thread`; whether it was there to receive it."""
    try:
        signal.pthread_kill(thread, INTERRUPT_SIGNAL)
    except ProcessLookupError:  # the main thread has ended: nothing left to interrupt
        return False
    return True


def stop_when_unheard(client: Any, stop: Callable[[], object]) -> threading.Event:
    """Call `stop` once `client` (a TaskManagerClient) no longer hears its Task Manager after
    a hold-up (it logs why); the event returned is set then: the program ends with
    EXIT_NODE_UNHEARD."""
    unheard = threading.Event()

    def unheard_after(_held_up_sec: float) -> None:
        if not unheard.is_set():
            unheard.set()
            stop()

    client.on_node_unheard(unheard_after)
    return unheard


def end_within(release: Callable[[], None], program: str, exit_code: int) -> None:
    """Run `release` (destroying the program's ROS entities, its work done); if it has not
    returned within END_TIMEOUT_SEC, say so in one line on stderr (with every thread's stack
    when faulthandler is on, e.g. PYTHONFAULTHANDLER=1) and end the process with `exit_code`.

    Fast DDS 3.2 can deadlock while it destroys a reader or a participant as another process
    leaves the domain (its timer thread and a receive thread each waiting for the other, the
    kind reported as eProsima/Fast-DDS#6502); a program whose work is done must not hang on it.

    It can also spin for good deleting the participant, holding the GIL (rclpy destroys the
    last node of a context, and with it the participant, without letting go of it): seen with
    `DomainParticipant::set_listener` waiting for a discovery callback that waits for a lock
    set_listener holds, a taskctl at 58 % of a core for minutes. No Python thread runs then, so
    the line above cannot be printed: faulthandler's watchdog, a thread of C that needs no GIL,
    ends the process LAST_RESORT_SEC later with exit code 1, after every thread's stack.
    """
    raised: list[BaseException] = []

    def run() -> None:
        try:
            release()
        except BaseException as error:  # raised again by the caller's thread
            raised.append(error)

    releasing = threading.Thread(target=run, name=f'{program}-end', daemon=True)
    faulthandler.dump_traceback_later(END_TIMEOUT_SEC + LAST_RESORT_SEC, exit=True)
    releasing.start()
    releasing.join(END_TIMEOUT_SEC)
    if not releasing.is_alive():
        faulthandler.cancel_dump_traceback_later()
        if raised:
            raise raised[0]
        return
    print(
        f'{program}: the ROS middleware did not shut down within {END_TIMEOUT_SEC:g} s; '
        'exiting anyway',
        file=sys.stderr,
        flush=True,
    )
    if faulthandler.is_enabled():
        faulthandler.dump_traceback(all_threads=True)
    sys.stdout.flush()
    os._exit(exit_code)
