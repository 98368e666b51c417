"""Where the fleet history lives unless `--database` says otherwise."""

import os
from pathlib import Path

DATABASE_FILE = Path('task_manager', 'console', 'fleet.sqlite')
"""Under ROS_HOME (~/.ros when it is unset), as the Task Manager keeps its own history."""


def ros_home() -> Path:
    """$ROS_HOME, or ~/.ros as ROS 2 has it."""
    return Path(os.environ.get('ROS_HOME') or Path.home() / '.ros')


def default_database_url() -> str:
    """`sqlite:///$ROS_HOME/task_manager/console/fleet.sqlite` (an absolute path)."""
    return f'sqlite:///{(ros_home() / DATABASE_FILE).absolute()}'
