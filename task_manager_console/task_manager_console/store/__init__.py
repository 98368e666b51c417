"""The fleet history: every result of every robot, stored once, in a database."""

from task_manager_console.store.fleet_history import (
    DatabaseUnavailable,
    FleetHistory,
    HistoryFilter,
)

__all__ = ['DatabaseUnavailable', 'FleetHistory', 'HistoryFilter']
