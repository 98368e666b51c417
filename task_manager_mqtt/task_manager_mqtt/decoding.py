"""One request message, read without trusting it: a request to run, or why it is refused.

Before anything parses it, its size, its UTF-8 and how deep it nests are checked (a
parser recurses into each level: 5,000 levels raise RecursionError), and a retained one is
refused (it would run again at every reconnection). A refusal is answered with an error
reply when the message has a usable `request_id` to address it to, and is otherwise a dead
letter: the request_id is read from the parsed document, or, of a message too large, too
deep or broken to parse, by a scan of its top level. Nothing here raises, whatever the
payload, and nothing here reaches a Task Manager.

`load_json` is the same guard for the documents the FleetClient receives from robots.
"""

import json
import re
from dataclasses import dataclass
from itertools import accumulate
from typing import Any

from pydantic import ValidationError

from task_manager.protocol import models, mqtt
from task_manager.protocol.errors import describe

MAX_DEPTH = 32
"""Nesting levels (objects and arrays) a request may have; a mission's task_data uses ~6."""
OPS = (
    'start_task', 'start_mission', 'cancel', 'stop', 'history', 'reprioritize', 'why', 'pause',
    'resume', 'schedule', 'unschedule', 'enable_schedules', 'schedules', 'confirm',
)  # fmt: skip

# a JSON string (escapes included) and each structural character; anything else between
_TOKEN = re.compile(rb'"[^"\\]*(?:\\.[^"\\]*)*"|[{}\[\]:,]', re.DOTALL)
_STRING = re.compile(rb'"[^"\\]*(?:\\.[^"\\]*)*"', re.DOTALL)
_NOT_BRACKET = re.compile(rb'[^\[\]{}]+')
# key: byte, value: its step in nesting depth
_DEPTH_STEP = tuple(1 if b in b'[{' else -1 if b in b']}' else 0 for b in range(256))
_REQUEST_ID_KEY = b'"request_id"'


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
        return Decoded(error=refusal('internal_error', message))


def _decode(payload: bytes, max_payload_bytes: int, retained: bool) -> Decoded:
    if len(payload) > max_payload_bytes:
        message = f'the request is {len(payload)} bytes; at most {max_payload_bytes} allowed'
        return _refused(payload[:max_payload_bytes], 'payload_too_large', message)
    try:
        text = payload.decode()
    except UnicodeDecodeError as error:
        message = f'not UTF-8 text: byte 0x{payload[error.start]:02x} at offset {error.start}'
        return _refused(payload, 'invalid_request', message)
    if deeper_than(payload, MAX_DEPTH):
        message = f'the request nests deeper than {MAX_DEPTH} levels; at most {MAX_DEPTH} allowed'
        return _refused(payload, 'nesting_too_deep', message)
    try:
        document = json.loads(text)
    except ValueError as error:
        return _refused(payload, 'invalid_request', f'not valid JSON: {error}')
    if not isinstance(document, dict):
        return Decoded(error=refusal('invalid_request', 'the message must be a JSON object'))
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
        return Decoded(request_id, op, error=refusal('retained_request', message))
    try:
        request = mqtt.RobotRequest.model_validate_json(payload).root
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
    return refusal('invalid_request', message, field)


def _usable_id(value: Any) -> str:
    return value if isinstance(value, str) and 0 < len(value) <= models.NAME_MAX else ''


def _id_problem(document: dict[str, Any]) -> dict[str, str]:
    if 'request_id' not in document:
        return refusal('invalid_request', 'request_id: required (replies are addressed by it)',
                       'request_id')  # fmt: skip
    value = document['request_id']
    given = f'{len(value)} characters' if isinstance(value, str) else type(value).__name__
    message = f'request_id: a string of 1 to {models.NAME_MAX} characters, got {given}'
    return refusal('invalid_request', message, 'request_id')


def deeper_than(payload: bytes, levels: int) -> bool:
    """Whether the JSON text `payload` nests objects and arrays deeper than `levels`.

    Linear, without recursion: strings are skipped (brackets in them do not count), then
    the depth is the highest running sum of +1 per opening and -1 per closing bracket.
    """
    brackets = _NOT_BRACKET.sub(b'', _STRING.sub(b'', payload))
    if len(brackets) <= levels:
        return False
    return max(accumulate(map(_DEPTH_STEP.__getitem__, brackets))) > levels


def top_level_request_id(payload: bytes) -> str:
    """The `request_id` of a top-level JSON object, read from its tokens without parsing it
    (it may be too large, too deep, or broken further on); empty if there is none usable."""
    tokens = _TOKEN.finditer(payload)
    first = next(tokens, None)
    if first is None or first.group() != b'{' or payload[: first.start()].strip():
        return ''
    depth = 1
    key = b''
    expected = 'key'  # at depth 1: key, colon, value, then comma (or the end)
    for match in tokens:
        token = match.group()
        if depth == 1:
            if expected == 'key':
                if not token.startswith(b'"'):
                    return ''
                key, expected = token, 'colon'
                continue
            if expected == 'colon':
                if token != b':':
                    return ''
                expected = 'value'
                continue
            if expected == 'value' and key == _REQUEST_ID_KEY:
                return _id_of_token(token)
            if token == b',':  # after a value (a number, true...: not a token here)
                expected = 'key'
                continue
            if token == b'}':
                return ''
            expected = 'comma'
        if token in (b'{', b'['):
            depth += 1
        elif token in (b'}', b']'):
            depth -= 1
    return ''


def _id_of_token(token: bytes) -> str:
    if not token.startswith(b'"'):
        return ''
    try:
        return _usable_id(json.loads(token))
    except ValueError:
        return ''


def load_json(payload: bytes, max_depth: int = MAX_DEPTH) -> Any:
    """A JSON document of at most `max_depth` levels; ValueError for anything else."""
    if deeper_than(payload, max_depth):
        raise ValueError(f'nested deeper than {max_depth} levels')
    return json.loads(payload)
