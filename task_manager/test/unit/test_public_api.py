"""The package root's public API: what `__all__` lists is exactly what it resolves."""

from types import ModuleType

import pytest


def test_all_lists_every_public_name_once_and_each_resolves(package_root: ModuleType) -> None:
    names = package_root.__all__

    assert names == sorted(names) and len(set(names)) == len(names)
    assert set(names) == set(package_root._DEFINED_IN)
    for name in names:
        value = getattr(package_root, name)
        assert value.__name__ == name and value.__module__ == package_root._DEFINED_IN[name]
    assert dir(package_root) == sorted(names)


def test_pause_and_schedule_api_is_public(package_root: ModuleType) -> None:
    client = package_root.TaskManagerClient
    for method in ('pause', 'resume', 'schedule_task', 'schedule_mission', 'unschedule'):
        assert callable(getattr(client, method))
    assert callable(client.enable_schedules) and callable(client.schedules)
    assert {'Pause', 'ScheduleInfo', 'OverlapPolicy', 'scheduled_next_run'} <= set(
        package_root.__all__
    )


def test_an_unknown_name_is_an_attribute_error(package_root: ModuleType) -> None:
    with pytest.raises(AttributeError, match="module 'task_manager' has no attribute 'nope'"):
        _ = package_root.nope
