"""Where a Task Manager keeps its task history when its parameters name no `history_path`.

One file per ROS domain and node, under ROS_HOME, so that Task Managers started with one
parameters file in several domains (two simulations, a rig with a robot per domain) never
share one: `$ROS_HOME/task_manager/domain<ROS_DOMAIN_ID>/<namespace/><node name>/history.sqlite`.

Versions before kept one `$ROS_HOME/task_manager/history.sqlite` for all; the first Task
Manager without a history_path that starts after the upgrade moves it to its own place
(`adopt_legacy_history`), so that no history is left behind unseen.
"""

import contextlib
import os
from pathlib import Path

from task_manager.core.history.store import lock_history

FOLDER = 'task_manager'
FILE_NAME = 'history.sqlite'
# The database and its write-ahead log files: they move together.
SQLITE_SUFFIXES = ('', '-wal', '-shm')


def ros_home() -> str:
    """`$ROS_HOME`, by default `~/.ros` (where ROS 2 keeps its logs too)."""
    return os.environ.get('ROS_HOME') or os.path.join(os.path.expanduser('~'), '.ros')


def default_history_path(home: str, domain_id: int, node_name: str) -> str:
    """The history file of the node `node_name` (fully qualified: `/robot1/task_manager`) on
    ROS domain `domain_id`, under the ROS_HOME `home`."""
    parts = [part for part in node_name.split('/') if part]
    return os.path.join(home, FOLDER, f'domain{domain_id}', *parts, FILE_NAME)


def legacy_history_path(home: str) -> str:
    """The one default history file of the versions before, under the ROS_HOME `home`."""
    return os.path.join(home, FOLDER, FILE_NAME)


def adopt_legacy_history(legacy: str, path: str) -> bool:
    """Move the history file `legacy` (with its log files) to `path` if `path` has none yet;
    whether it did.

    Raises HistoryInUseError while a running Task Manager (of a version before) holds it,
    and OSError when it cannot be moved.
    """
    if os.path.exists(path) or not os.path.exists(legacy):
        return False
    lock = lock_history(legacy)
    try:
        if os.path.exists(path) or not os.path.exists(legacy):  # another one was quicker
            return False
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        for suffix in reversed(SQLITE_SUFFIXES):  # the database last: it is what is looked for
            if os.path.exists(legacy + suffix):
                os.replace(legacy + suffix, path + suffix)
        with contextlib.suppress(FileNotFoundError):
            os.remove(f'{legacy}.lock')
        return True
    finally:
        lock.close()
