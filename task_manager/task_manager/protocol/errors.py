"""The protocol's error answers: the code of each (`RefusalCode`), and a pydantic validation
error as one message and the field at fault."""

from collections.abc import Iterable, Sequence
from enum import StrEnum
from typing import Any

from task_manager.core.status import ErrorCode

MAX_ERRORS_SHOWN = 5


class RefusalCode(StrEnum):
    """The `code` of every error answer of a gateway (`{"error": {"code", "message", "field"}}`
    of the web gateway and the fleet console, an MQTT reply's `error`, a FleetError): why a
    request was refused, or why it could not be answered. docs/security.md says which door
    answers which."""

    INVALID_REQUEST = ErrorCode.INVALID_REQUEST.value
    """A field, a document or its JSON is refused; the message says what is allowed."""
    PAYLOAD_TOO_LARGE = 'payload_too_large'
    """An MQTT message (a request, or one a FleetClient would send) over the size allowed."""
    NESTING_TOO_DEEP = 'nesting_too_deep'
    """JSON nested deeper than core/bounds.py's JSON_MAX_DEPTH."""
    RETAINED_REQUEST = 'retained_request'
    """An MQTT request published with the retain flag."""
    REPLY_TOO_LARGE = 'reply_too_large'
    """An MQTT reply that would not fit in a message: ask for less."""
    TASK_MANAGER_UNAVAILABLE = 'task_manager_unavailable'
    """No Task Manager answers."""
    INTERNAL_ERROR = 'internal_error'
    """The gateway itself failed (one log line; never a traceback to the client)."""
    UNKNOWN_TASK_ID = 'unknown_task_id'
    """The Task Manager knows no such task (neither active nor in its history)."""
    UNKNOWN_SCHEDULE_ID = 'unknown_schedule_id'
    """The Task Manager has no such schedule."""
    NOT_WAITING = 'not_waiting'
    """An answer to a task that is no system/confirm waiting for it."""
    UNAUTHORIZED = 'unauthorized'
    """No token, or an unknown one."""
    FORBIDDEN = 'forbidden'
    """A token whose role is below what the request needs."""
    NOT_FOUND = 'not_found'
    """No such route or page."""
    METHOD_NOT_ALLOWED = 'method_not_allowed'
    BODY_TOO_LARGE = 'body_too_large'
    BODY_TIMEOUT = 'body_timeout'
    """A request body that did not arrive in time."""
    HOST_NOT_ALLOWED = 'host_not_allowed'
    """A `Host` header that names no name of the gateway."""
    TOO_MANY_REQUESTS = 'too_many_requests'
    """Too many reads of one client in flight."""
    UNKNOWN_ROBOT = 'unknown_robot'
    """The fleet console knows no such robot."""
    ROBOT_OFFLINE = 'robot_offline'
    """The robot asked for is not connected to the broker."""
    NO_ROBOT = 'no_robot'
    """No robot of those asked for can take the task."""
    ROBOT_ERROR = 'robot_error'
    """A robot refused, without a code of its own."""
    BAD_REPLY = 'bad_reply'
    """A robot's reply that is not the protocol's."""
    TIMEOUT = 'timeout'
    """No reply within the time allowed."""
    REFUSED_BY_BROKER = 'refused_by_broker'
    """The broker refused to take a message (e.g. not authorized)."""
    DATABASE_UNAVAILABLE = 'database_unavailable'
    """The fleet history's database does not answer."""


def field_of(location: Iterable[Any], skip: Sequence[str] = ()) -> str:
    """A dotted field path from a pydantic error location, without the parts in `skip`."""
    return '.'.join(str(part) for part in location if part not in skip)


def _message(error: Any, skip: Sequence[str]) -> str:
    field = field_of(error.get('loc', ()), skip)
    message = str(error.get('msg', 'invalid'))
    kind = error.get('type')
    if kind == 'extra_forbidden':
        message = 'unknown field (see the schema for the fields allowed)'
    if kind in ('model_attributes_type', 'dict_type') and not field:
        return 'the message must be a JSON object'
    if kind == 'json_invalid':
        context = error.get('ctx') or {}
        return f'not valid JSON: {context.get("error", message)}'
    if kind == 'union_tag_not_found':
        return f'{field}: missing field "op"' if field else 'missing field "op"'
    return f'{field}: {message}' if field else message


def describe(errors: Sequence[Any], skip: Sequence[str] = ()) -> tuple[str, str]:
    """(message, field) of pydantic's `errors()`: the first few joined, the first one's field.

    `skip`: location parts that name no field (e.g. 'body', or a union's tag).
    """
    first = errors[0] if errors else {}
    message = '; '.join(_message(each, skip) for each in errors[:MAX_ERRORS_SHOWN])
    # the location of invalid JSON is a character offset, not a field
    field = '' if first.get('type') == 'json_invalid' else field_of(first.get('loc', ()), skip)
    return message or 'invalid request', field
