"""Finding the generated Python class of a declared task's msg_interface."""

import importlib
from typing import Any

from task_manager.core.errors import ConfigurationError
from task_manager.core.task_spec import TaskKind, TaskSpec

_REQUIRED_PARTS = {
    TaskKind.ACTION: ('Goal', 'Result', 'Feedback'),
    TaskKind.SERVICE: ('Request', 'Response'),
}


def load_interface(spec: TaskSpec) -> Any:
    """Import the action or service class of `spec`; ConfigurationError names the task."""
    interface = spec.interface
    label = f"task '{spec.task_name}'"
    try:
        module = importlib.import_module(f'{interface.package}.{interface.kind}')
        interface_class = getattr(module, interface.name)
    except (ImportError, AttributeError) as error:
        raise ConfigurationError(
            f'{label}: unknown msg_interface {interface} (cannot import it: {error})'
        ) from error
    missing = [p for p in _REQUIRED_PARTS[interface.kind] if not hasattr(interface_class, p)]
    if missing:
        raise ConfigurationError(f'{label}: msg_interface {interface} is not a {interface.kind}')
    _check_success_field(spec, interface_class)
    return interface_class


def _check_success_field(spec: TaskSpec, interface_class: Any) -> None:
    if not spec.service_success_field:
        return
    fields = interface_class.Response.get_fields_and_field_types()
    if fields.get(spec.service_success_field) != 'boolean':
        bool_fields = [name for name, kind in fields.items() if kind == 'boolean']
        raise ConfigurationError(
            f"task '{spec.task_name}': service_success_field "
            f"'{spec.service_success_field}' is not a bool field of the {spec.interface} "
            f'response (bool fields: {", ".join(bool_fields) or "none"})'
        )
