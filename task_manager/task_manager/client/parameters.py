"""The declared tasks, read from the Task Manager's parameters, and the system tasks."""

from typing import Any

from rcl_interfaces.srv import GetParameters, ListParameters
from rclpy.parameter import parameter_value_to_python

from task_manager.client.services import CallService
from task_manager.core.system_tasks import SYSTEM_SPECS

TASK_MANAGER_NODE = '/task_manager'
LIST_PARAMETERS_SERVICE = f'{TASK_MANAGER_NODE}/list_parameters'
GET_PARAMETERS_SERVICE = f'{TASK_MANAGER_NODE}/get_parameters'


def declared_tasks(call: CallService) -> list[dict[str, Any]]:
    """The declared tasks and their properties, then the system tasks.

    Through the client's own two clients of the node's parameter services (`call` makes each
    once): a parameter client per call (rclpy's AsyncParameterClient makes six) was never
    destroyed, and every process of the domain grew with each read.
    """
    listed = call(ListParameters, LIST_PARAMETERS_SERVICE, ListParameters.Request())
    names = list(listed.result.names)
    got = call(GetParameters, GET_PARAMETERS_SERVICE, GetParameters.Request(names=names))
    values = {n: parameter_value_to_python(v) for n, v in zip(names, got.values, strict=True)}
    return [*_declared_in(values), *_system_tasks()]


def _declared_in(values: dict[str, Any]) -> list[dict[str, Any]]:
    return [
        {
            'key': key,
            **{n[len(key) + 1 :]: v for n, v in values.items() if n.startswith(f'{key}.')},
        }
        for key in values.get('tasks') or []
    ]


def _system_tasks() -> list[dict[str, Any]]:
    return [
        {
            'key': '',
            'task_name': spec.task_name,
            'msg_interface': str(spec.interface),
            'topic': '',
            'blocking': spec.blocking,
            'cancel_on_stop': spec.cancel_on_stop,
            'reentrant': spec.reentrant,
            'cancel_reported_as_success': spec.cancel_reported_as_success,
            'cancel_timeout': spec.cancel_timeout_sec,
            'pause': spec.pause.value,
        }
        for spec in SYSTEM_SPECS
    ]
