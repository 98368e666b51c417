"""The package root's public API: what `__all__` lists is exactly what it resolves."""

import pytest

import task_manager


def test_all_lists_every_public_name_once_and_each_resolves() -> None:
    names = task_manager.__all__

    assert names == sorted(names) and len(set(names)) == len(names)
    assert set(names) == set(task_manager._DEFINED_IN)
    for name in names:
        value = getattr(task_manager, name)
        assert value.__name__ == name and value.__module__ == task_manager._DEFINED_IN[name]
    assert dir(task_manager) == sorted(names)


def test_pause_and_schedule_api_is_public() -> None:
    client = task_manager.TaskManagerClient
    for method in ('pause', 'resume', 'schedule_task', 'schedule_mission', 'unschedule'):
        assert callable(getattr(client, method))
    assert callable(client.enable_schedules) and callable(client.schedules)
    assert {'Pause', 'ScheduleInfo', 'OverlapPolicy', 'scheduled_next_run'} <= set(
        task_manager.__all__
    )


def test_an_unknown_name_is_an_attribute_error() -> None:
    with pytest.raises(AttributeError, match="module 'task_manager' has no attribute 'nope'"):
        _ = task_manager.nope
