"""Every name and limit of the Task Manager on the wire, defined once.

The node, the client, the gateways and the tests import them from here: the node's name, its
action, topics and services, the system tasks, the source of a mission's subtasks, and the
limits a request is held to (their values in core/bounds.py, the home of every bound).
"""

from task_manager.core import bounds

NODE_NAME = 'task_manager'

# ---- the node's public ROS interfaces (INTERFACES.md, then ours) --------------------------------
EXECUTE_TASK_ACTION = '/task_manager/execute_task'
START_TASK_ACTION = '/task_manager/start_task'
"""ExecuteTask with options (StartTask): priority, on conflict, timeouts."""
ACTIVE_TASKS_TOPIC = '/task_manager/active_tasks'
RESULTS_TOPIC = '/task_manager/results'
TASK_EVENTS_TOPIC = '/task_manager/task_events'
TASK_EVENT_BATCHES_TOPIC = '/task_manager/task_event_batches'
"""The events of TASK_EVENTS_TOPIC, in order, one TaskEventArray per turn of the node."""
INSTANCES_TOPIC = '/task_manager/instances'
GET_TASK_RESULTS_SERVICE = '/task_manager/get_task_results'
GET_TASK_STATES_SERVICE = '/task_manager/get_task_states'
QUERY_TASK_HISTORY_SERVICE = '/task_manager/query_task_history'
GET_SCHEDULES_SERVICE = '/task_manager/get_schedules'
CONFIRM_TASK_SERVICE = '/task_manager/confirm_task'
"""ConfirmTask: answer a waiting system/confirm (confirm or reject)."""
TASK_SERVER_PREFIX = '/task_manager/task/'
"""With enable_task_servers, task NAME is also served at TASK_SERVER_PREFIX + NAME."""
LIST_PARAMETERS_SERVICE = f'/{NODE_NAME}/list_parameters'
GET_PARAMETERS_SERVICE = f'/{NODE_NAME}/get_parameters'
"""The node's parameter services (rclpy's own): where the declared tasks are read."""

# ---- the system tasks ---------------------------------------------------------------------------
MISSION = 'system/mission'
CANCEL_TASK = 'system/cancel_task'
CANCEL_TASK_ALIAS = 'system/cancel_tasks'
"""The seed's other name for system/cancel_task."""
STOP = 'system/stop'
WAIT = 'system/wait'
PAUSE = 'system/pause'
RESUME = 'system/resume'
SCHEDULE = 'system/schedule'
UNSCHEDULE = 'system/unschedule'
ENABLE_SCHEDULE = 'system/enable_schedule'
REPRIORITIZE = 'system/reprioritize'
CONFIRM = 'system/confirm'
SYSTEM_TASK_NAMES = frozenset(
    {
        CONFIRM,
        REPRIORITIZE,
        MISSION,
        CANCEL_TASK,
        CANCEL_TASK_ALIAS,
        STOP,
        WAIT,
        PAUSE,
        RESUME,
        SCHEDULE,
        UNSCHEDULE,
        ENABLE_SCHEDULE,
    }
)

MISSION_SOURCE = 'Mission'
"""The source of a mission's subtasks."""

# ---- limits -------------------------------------------------------------------------------------
HISTORY_QUERY_LIMIT_MAX = 10_000
"""The most rows one /task_manager/query_task_history answer holds."""
HISTORY_QUERY_LIMIT_DEFAULT = 100
"""The rows of a history query that names no limit."""
IDS_MAX = bounds.IDS_MAX
"""The most task ids in one request, and subtasks in one mission (core/bounds.py)."""
