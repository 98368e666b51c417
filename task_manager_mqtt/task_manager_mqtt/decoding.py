"""One request message, read without trusting it: a request to run, or why it is refused.

Before anything parses it, its size, how deep it nests and its UTF-8 are checked, and then it
must be plain JSON (no key twice, no NaN): the shared reader of every door,
`task_manager.protocol.strict_json`, in time linear in the message's length. A retained one is
refused (it would run again at every reconnection). A refusal is answered with an error
reply when the message has a usable `request_id` to address it to, and is otherwise a dead
letter: the request_id is read from the parsed document, or, of a message too large, too
deep or broken to parse, by a scan of its top level (linear too). Nothing here raises,
whatever the payload, and nothing here reaches a Task Manager.
"""

import json
import re
from dataclasses import dataclass
from typing import Any

from pydantic import ValidationError

from task_manager.protocol import models, mqtt
from task_manager.protocol.errors import RefusalCode, describe
from task_manager.protocol.strict_json import MAX_DEPTH, RefusedJsonError, load

OPS = (
    'start_task', 'start_mission', 'cancel', 'stop', 'history', 'reprioritize', 'why', 'pause',
    'resume', 'schedule', 'unschedule', 'enable_schedules', 'schedules', 'confirm',
)  # fmt: skip

_SPACE = rb'[ \t\n\r]*+'
_STRING = rb'"[^"\\]*+(?:\\.[^"\\]*+)*+"'
_OTHER = rb'[^\[\]{}"]++'
"""In an object or array: anything but a string or a bracket."""


def _container(levels: int) -> bytes:
    """An object or array nested at most `levels` deep, as a regular expression."""
    content = _STRING + b'|' + _OTHER
    for _ in range(levels - 1):
        content = rb'[\[{](?:' + content + rb')*+[\]}]|' + _STRING + b'|' + _OTHER
    return rb'[\[{](?:' + content + rb')*+[\]}]'


_VALUE = rb'(?:' + _STRING + rb'|[^ \t\n\r\[\]{}",:]++|' + _container(MAX_DEPTH - 1) + rb')'
_TOP_LEVEL_REQUEST_ID = re.compile(
    _SPACE + rb'\{(?:' + _SPACE + rb'(?!"request_id"' + _SPACE + rb':)' + _STRING + _SPACE + rb':'
    + _SPACE + _VALUE + _SPACE + rb',)*+' + _SPACE + rb'"request_id"' + _SPACE + rb':' + _SPACE
    + rb'(?P<request_id>' + _STRING + rb')',
    re.DOTALL,
)  # fmt: skip
"""From the start of a message: `{`, its keys and values (nested at most MAX_DEPTH levels
with the object), up to a key `request_id` and its string value."""


@dataclass(frozen=True)
class Decoded:
    """Either `request` (valid, to run) or `error` (an ErrorDetail document); never both."""

    request_id: str = ''
    """Usable to address a reply: a string of 1 to NAME_MAX characters; else empty."""
    op: str = ''
    request: Any = None
    """A request model of mqtt.RobotRequest (StartTaskRequest, ...)."""
    error: dict[str, str] | None = None

    @property
    def addressed(self) -> bool:
        """Whether a reply can be addressed (else a refusal is a dead letter)."""
        return bool(self.request_id)


def refusal(code: str, message: str, field: str = '') -> dict[str, str]:
    return {'code': code, 'message': message, 'field': field}


def decode(payload: bytes, max_payload_bytes: int, retained: bool = False) -> Decoded:
    """The request in `payload`, or why it is refused (see the module's docstring)."""
    try:
        return _decode(payload, max_payload_bytes, retained)
    except Exception as error:  # a safety net: every message must still end in an answer
        message = f'the bridge could not read the request: {type(error).__name__}'
        return Decoded(error=refusal(RefusalCode.INTERNAL_ERROR, message))


def _decode(payload: bytes, max_payload_bytes: int, retained: bool) -> Decoded:
    try:
        document = load(payload, MAX_DEPTH, max_payload_bytes)
    except RefusedJsonError as refused:
        return _refused(payload[:max_payload_bytes], refused.code, refused.message)
    if not isinstance(document, dict):
        return Decoded(
            error=refusal(RefusalCode.INVALID_REQUEST, 'the message must be a JSON object')
        )
    op = document.get('op')
    op = op if op in OPS else ''
    request_id = _usable_id(document.get('request_id'))
    if not request_id:
        return Decoded(op=op, error=_id_problem(document))
    if retained:
        message = (
            'retained requests are refused (one would run again at every reconnection); '
            'publish requests without the retain flag'
        )
        return Decoded(request_id, op, error=refusal(RefusalCode.RETAINED_REQUEST, message))
    try:
        request = mqtt.RobotRequest.model_validate(document).root
    except ValidationError as error:
        return Decoded(request_id, op, error=_invalid(error))
    return Decoded(request_id, op, request=request)


def _refused(payload: bytes, code: str, message: str) -> Decoded:
    """A message not parsed: refused, addressed to its top-level request_id if it has one."""
    return Decoded(top_level_request_id(payload), error=refusal(code, message))


def _invalid(error: ValidationError) -> dict[str, str]:
    message, field = describe(error.errors(), skip=OPS)
    if error.errors()[0].get('type') == 'union_tag_invalid':
        message = f'unknown op; allowed: {", ".join(OPS)}'
        field = 'op'
    return refusal(RefusalCode.INVALID_REQUEST, message, field)


def _usable_id(value: Any) -> str:
    return value if isinstance(value, str) and 0 < len(value) <= models.NAME_MAX else ''


def _id_problem(document: dict[str, Any]) -> dict[str, str]:
    if 'request_id' not in document:
        message = 'request_id: required (replies are addressed by it)'
        return refusal(RefusalCode.INVALID_REQUEST, message, 'request_id')
    value = document['request_id']
    given = f'{len(value)} characters' if isinstance(value, str) else type(value).__name__
    message = f'request_id: a string of 1 to {models.NAME_MAX} characters, got {given}'
    return refusal(RefusalCode.INVALID_REQUEST, message, 'request_id')


def top_level_request_id(payload: bytes) -> str:
    """The `request_id` of a top-level JSON object, read by one regular expression without
    parsing the object (it may be too large, too deep, or broken further on): the keys and
    values before it (each nested at most MAX_DEPTH levels) are passed over; empty if there
    is none usable."""
    found = _TOP_LEVEL_REQUEST_ID.match(payload)
    return _id_of_token(found.group('request_id')) if found else ''


def _id_of_token(token: bytes) -> str:
    try:
        return _usable_id(json.loads(token))
    except ValueError:
        return ''
