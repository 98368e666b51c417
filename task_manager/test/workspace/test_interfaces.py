"""The generated task_manager_msgs types equal the wire contract in INTERFACES.md."""

import pytest
from task_manager_msgs.action import ExecuteTask, Mission, Wait
from task_manager_msgs.msg import (
    ActiveTask,
    ActiveTaskArray,
    SubtaskGoal,
    SubtaskResult,
    TaskDoneResult,
    TaskManagerInstance,
    TaskStatus,
)
from task_manager_msgs.srv import CancelTasks, GetTaskResults, StopTasks

from task_manager.testing.messages import GeneratedMessage

# key: generated class, value: its fields in wire order as (name, rosidl type)
EXPECTED_FIELDS = {
    ExecuteTask.Goal: [
        ('task_id', 'string'),
        ('task_name', 'string'),
        ('source', 'string'),
        ('task_data', 'string'),
    ],
    ExecuteTask.Result: [
        ('task_id', 'string'),
        ('task_result', 'string'),
        ('task_status', 'string'),
        ('error_code', 'string'),
    ],
    ExecuteTask.Feedback: [],
    TaskStatus: [],
    ActiveTask: [
        ('task_id', 'string'),
        ('task_name', 'string'),
        ('task_status', 'string'),
        ('source', 'string'),
    ],
    ActiveTaskArray: [('active_tasks', 'sequence<task_manager_msgs/ActiveTask>')],
    TaskDoneResult: [
        ('task_id', 'string'),
        ('task_name', 'string'),
        ('task_status', 'string'),
        ('error_code', 'string'),
        ('source', 'string'),
        ('task_result', 'string'),
    ],
    SubtaskGoal: [
        ('task_id', 'string'),
        ('task_name', 'string'),
        ('task_data', 'string'),
        ('allow_skipping', 'boolean'),
    ],
    SubtaskResult: [
        ('task_id', 'string'),
        ('task_name', 'string'),
        ('task_status', 'string'),
        ('skipped', 'boolean'),
    ],
    Mission.Goal: [('subtasks', 'sequence<task_manager_msgs/SubtaskGoal>')],
    Mission.Result: [('mission_results', 'sequence<task_manager_msgs/SubtaskResult>')],
    Mission.Feedback: [],
    Wait.Goal: [('duration', 'float')],
    Wait.Result: [],
    Wait.Feedback: [('remaining_time', 'double')],
    CancelTasks.Request: [('cancelled_tasks', 'sequence<string>')],
    CancelTasks.Response: [('success', 'boolean'), ('successful_cancels', 'sequence<string>')],
    GetTaskResults.Request: [('max_results', 'uint32')],
    GetTaskResults.Response: [('results', 'sequence<task_manager_msgs/TaskDoneResult>')],
    StopTasks.Request: [],
    StopTasks.Response: [('success', 'boolean')],
    # New types (not in the original package)
    TaskManagerInstance: [
        ('started', 'builtin_interfaces/Time'),
        ('host', 'string'),
        ('pid', 'int32'),
        ('instance_id', 'string'),
    ],
}

# key: generated class, value: its constants (name -> value)
EXPECTED_CONSTANTS = {
    ExecuteTask.Result: {
        'ERROR_DUPLICATE_TASK_ID': 'duplicate_id',
        'ERROR_TASK_DATA_PARSING_FAILED': 'task_data_parsing_failed',
        'ERROR_TASK_START_ERROR': 'task_start_failed',
        'ERROR_TASK_CANCEL_FAILED': 'task_cancel_failed',
        'ERROR_UNKNOWN_TASK': 'unknown_task',
    },
    TaskStatus: {
        'RECEIVED': 'RECEIVED',
        'IN_PROGRESS': 'IN_PROGRESS',
        'DONE': 'DONE',
        'ERROR': 'ERROR',
        'CANCELED': 'CANCELED',
    },
}


def _user_fields(msg_class: type[GeneratedMessage]) -> list[tuple[str, str]]:
    # Messages without fields get a generated placeholder member; it is not on the wire
    # of the original either (same .msg source), so it is left out of the comparison.
    return [
        (name, kind)
        for name, kind in msg_class.get_fields_and_field_types().items()
        if name != 'structure_needs_at_least_one_member'
    ]


@pytest.mark.parametrize('msg_class', list(EXPECTED_FIELDS), ids=lambda c: c.__qualname__)
def test_fields_types_and_order_match_the_spec(msg_class: type[GeneratedMessage]) -> None:
    assert _user_fields(msg_class) == EXPECTED_FIELDS[msg_class]


def _declared_constants(msg_class: type) -> dict[str, object]:
    # rosidl keeps a class's constants in its metaclass, as a name-mangled dict.
    metaclass = type(msg_class)
    return dict(getattr(metaclass, f'_{metaclass.__name__}__constants'))


@pytest.mark.parametrize('msg_class', list(EXPECTED_FIELDS), ids=lambda c: c.__qualname__)
def test_constants_match_the_spec(msg_class: type) -> None:
    expected = EXPECTED_CONSTANTS.get(msg_class, {})
    assert _declared_constants(msg_class) == expected
    assert {name: getattr(msg_class, name) for name in expected} == expected
