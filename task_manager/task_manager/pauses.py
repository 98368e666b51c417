"""The pause records of the client, where they were before `task_manager.client` was a package
(taskctl imports them from here)."""

from task_manager.client.records import Pause, parse_pauses, paused_time, running_time

__all__ = ['Pause', 'parse_pauses', 'paused_time', 'running_time']
