"""`enable_task_servers`: each task also served at /task_manager/task/<task_name>.

For debugging and the CLI: goals and requests use the task's own interface and go through
the same dispatcher (conflicts, tracking, results) as ExecuteTask, with source `task_server`.
"""

from typing import Any

from rclpy.action.server import ActionServer, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node

from task_manager.core.names import TASK_SERVER_PREFIX
from task_manager.core.task import TaskRecord, TaskRequest
from task_manager.core.task_spec import TaskKind, TaskSpec
from task_manager.messages.json_codec import TaskDataError, message_from_dict, message_to_json
from task_manager.ros.interfaces import load_interface
from task_manager.ros.running.protocols import TaskRunning
from task_manager.ros.serving.goal_binding import GoalTaskBinding, GoalTasks

TASK_SERVER_SOURCE = 'task_server'


def task_server_name(task_name: str) -> str:
    return TASK_SERVER_PREFIX + task_name.strip('/')


def _message_of_result(message_class: Any, record: TaskRecord) -> Any:
    """The task's result as its own message type; defaults when there is none."""
    try:
        return (
            message_class()
            if not record.result
            else message_from_dict(message_class, record.result)
        )
    except TaskDataError:
        return message_class()


def _request(spec: TaskSpec, message: Any) -> TaskRequest:
    return TaskRequest('', spec.task_name, TASK_SERVER_SOURCE, message_to_json(message))


def create_task_servers(node: Node, tasks: GoalTasks, specs: list[TaskSpec]) -> list[Any]:
    """Create an action server or service per declared task; return them."""
    binding = GoalTaskBinding(node, tasks)
    servers = []
    for spec in specs:
        interface_class = load_interface(spec)
        name = task_server_name(spec.task_name)
        if spec.kind is TaskKind.ACTION:
            servers.append(_action_server(node, binding, spec, interface_class, name))
        else:
            servers.append(_service(node, tasks, spec, interface_class, name))
    return servers


def _action_server(
    node: Node, binding: GoalTaskBinding, spec: TaskSpec, action_type: Any, name: str
) -> ActionServer[Any, Any, Any]:
    async def execute(goal_handle: Any) -> Any:
        record = await binding.run(
            goal_handle, _request(spec, goal_handle.request), action_type.Feedback
        )
        return _message_of_result(action_type.Result, record)

    return ActionServer(
        node,
        action_type,
        name,
        execute_callback=execute,
        goal_callback=lambda _: GoalResponse.ACCEPT,
        cancel_callback=binding.cancel_callback,
        callback_group=ReentrantCallbackGroup(),
    )


def _service(node: Node, tasks: TaskRunning, spec: TaskSpec, service_type: Any, name: str) -> Any:
    async def call(request: Any, _response: Any) -> Any:
        record = await tasks.run(_request(spec, request))
        return _message_of_result(service_type.Response, record)

    # A pending coroutine holds a mutually exclusive group, which would block the replies
    # of the task's own server: the service gets a reentrant group of its own.
    return node.create_service(service_type, name, call, callback_group=ReentrantCallbackGroup())
