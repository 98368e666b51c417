"""Every bound on what a request may carry and on what the Task Manager keeps, in one place.

Each door (the node's ROS interfaces, the web gateway, the MQTT bridge, the VDA 5050 adapter,
schedules read back from disk) checks against these same values and refuses what breaks one
with `invalid_request`, naming the field and the bound; `docs/security.md` lists them. Plain
Python, no rclpy: the gateways and the protocol import it too.
"""

import math
from dataclasses import dataclass

__all__ = [
    'COUNT',
    'DECISIONS_PER_TASK_MAX',
    'DELAY_SECONDS',
    'ECHO_MAX_CHARACTERS',
    'EPOCH_SECONDS',
    'EVENT_BATCH_MAX_BYTES',
    'FLEET_HISTORY_ROWS_DEFAULT',
    'FLEET_HISTORY_ROWS_MAX',
    'FLEET_RESULTS_HELD_MAX',
    'HISTORY_BYTES_DEFAULT',
    'HISTORY_PAGE_MAX_BYTES',
    'HISTORY_RESULT_MAX_BYTES',
    'HISTORY_TASK_DATA_MAX_BYTES',
    'IDS_MAX',
    'JSON_MAX_DEPTH',
    'PERIOD_SECONDS',
    'PRIORITY',
    'REASON_MAX_CHARACTERS',
    'SCHEDULES_MAX',
    'SECONDS',
    'TASK_DATA_MAX_BYTES',
    'TEXT_MAX_CHARACTERS',
    'TOKEN_MIN_CHARACTERS',
    'VDA5050_ACTIONS_MAX',
    'VDA5050_ID_MAX_CHARACTERS',
    'VDA5050_INSTANT_ACTIONS_KEPT',
    'VDA5050_LIST_MAX',
    'VDA5050_NUMBER',
    'VDA5050_RESULT_DESCRIPTION_MAX_CHARACTERS',
    'VDA5050_STATE_ACTIONS_MAX',
    'VDA5050_STATE_ERRORS_MAX',
    'VDA5050_TEXT_MAX_CHARACTERS',
    'VDA5050_UINT32',
    'VDA5050_UPDATES_WAITING_MAX',
    'VDA5050_WAITING_MAX_BYTES',
    'NumberBound',
    'check_wait_seconds',
    'cut_text',
    'duplicate_problem',
    'ids_problem',
    'task_data_problem',
]


@dataclass(frozen=True)
class NumberBound:
    """A closed range [low, high] a number must lie in; NaN and infinities are never in it."""

    low: float
    high: float
    unit: str = ''
    """'s' for seconds: said after the numbers in a refusal."""

    def problem(self, field: str, value: object) -> str:
        """Why `value` may not be `field`; empty when it may."""
        if isinstance(value, bool) or not isinstance(value, int | float):
            return f'{field} must be a number, got {type(value).__name__}'
        if isinstance(value, float) and not math.isfinite(value):
            return f'{field} must be a finite number, got {value!r}'
        if not self.low <= value <= self.high:
            unit = f' {self.unit}' if self.unit else ''
            return (
                f'{field} must be from {_number(self.low)} to {_number(self.high)}{unit}, '
                f'got {value!r}'
            )
        return ''

    def check(self, field: str, value: object) -> None:
        """Raise ValueError with problem() when `value` is out of bounds."""
        if problem := self.problem(field, value):
            raise ValueError(problem)


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else str(value)


# ---- seconds ------------------------------------------------------------------------------------
SECONDS = NumberBound(0.0, 7 * 24 * 3600.0, 's')
"""Any timeout, wait, grace, backoff or confirmation: at most a week. A ROS timer holds its
period in signed 64-bit nanoseconds (292 years); a week keeps every sum of them far from it."""


def check_wait_seconds(timeout_sec: float | None) -> None:
    """A client call's wait: None (its default, or for good, as the call says) or SECONDS (an
    infinite one reached threading's waits as OverflowError); ValueError otherwise."""
    if timeout_sec is not None:
        SECONDS.check('timeout_sec', timeout_sec)


PERIOD_SECONDS = NumberBound(0.1, 366 * 24 * 3600.0, 's')
"""A schedule's period: at most ten runs a second (one every 0.001 s ran 200 times a second and
kept doing so after restarts), at most a year."""
DELAY_SECONDS = NumberBound(0.0, 366 * 24 * 3600.0, 's')
"""A schedule's delay before its one run: at most a year."""
EPOCH_SECONDS = NumberBound(0.0, 253_402_300_799.0, 's')
"""An instant as seconds since 1970 (a schedule's at, start, end): up to 9999-12-31 23:59:59 UTC,
the last instant a datetime can hold."""

# ---- numbers ------------------------------------------------------------------------------------
PRIORITY = NumberBound(-(2**31), 2**31 - 1)
"""A task's priority: the int32 of TaskOptions."""
COUNT = NumberBound(0, 2**31 - 1)
"""A count a request gives (a schedule's max_runs)."""

# ---- sizes and counts ---------------------------------------------------------------------------
TEXT_MAX_CHARACTERS = 256
"""A task id, task name, source or schedule name."""
TASK_DATA_MAX_BYTES = 1_048_576
"""A request's task_data (JSON text, UTF-8): the gateways' largest body, at every door."""
HISTORY_TASK_DATA_MAX_BYTES = 16_384
"""What the history keeps of a request's task_data; a larger one is kept as a note of its size."""
HISTORY_RESULT_MAX_BYTES = 65_536
"""What the history keeps of a task's result; a larger one is kept as a note of its size."""
JSON_MAX_DEPTH = 32
"""How deep objects and arrays may nest in any JSON document a door reads."""
IDS_MAX = 1000
"""The most task ids in one request (cancel, pause, resume, reprioritize), and subtasks in one
mission; an id may appear once."""
DECISIONS_PER_TASK_MAX = 100
"""The decisions a task keeps: its first ones and its newest, with a count of those left out."""
REASON_MAX_CHARACTERS = 1000
"""A decision's reason as a task keeps it, and a task's error message in a document that must
be made smaller to fit its channel: longer ones are cut, with a note of how much was left out."""
HISTORY_BYTES_DEFAULT = 1_073_741_824
"""The bytes the history keeps of ended tasks unless `history_max_bytes` says otherwise: the
oldest beyond it are deleted, as beyond `history_max_results`."""
HISTORY_PAGE_MAX_BYTES = 8_388_608
"""The largest history page the web gateway answers (its JSON or CSV); more tasks than fit in
it are refused with `reply_too_large`, as MQTT refuses a reply over its message size."""
SCHEDULES_MAX = 1000
"""The schedules one Task Manager keeps."""
EVENT_BATCH_MAX_BYTES = 1_048_576
"""The most of one message on /task_manager/task_event_batches, counted as its events' text
(feedback, result, decisions, pauses); an event larger than it goes in a message alone."""
ECHO_MAX_CHARACTERS = 200
"""The most of a caller's own text (an unknown name, a bad value) an error message repeats."""
TOKEN_MIN_CHARACTERS = 16
"""The shortest token of the web gateway's token file, whatever the line's format: 16 printable
characters are over 100 bits when drawn at random (`secrets.token_urlsafe(24)` makes 32)."""


UPDATES_UNREAD_MAX = 10_000
"""Updates (active lists, results, task events, feedback) one iterator of the Python client
keeps unread; it drops the next ones, and its reader then gets FellBehind in their place."""


# ---- the fleet console --------------------------------------------------------------------------
FLEET_HISTORY_ROWS_DEFAULT = 100
"""The results a query of the fleet history returns when it asks for no `limit`."""
FLEET_HISTORY_ROWS_MAX = 10_000
"""The most results one query of the fleet history returns (its `limit`)."""
FLEET_RESULTS_HELD_MAX = 10_000
"""Results the console has received and not yet stored (nor acknowledged to the broker): its
MQTT Receive Maximum. While its database is away the broker keeps the rest."""

# ---- the VDA 5050 adapter ---------------------------------------------------------------------
VDA5050_ID_MAX_CHARACTERS = 100
"""An id (orderId, nodeId, edgeId, actionId, mapId, zoneSetId, startNodeId, endNodeId), a type
or a key (actionType, blockingType, direction, an actionParameter's key) of a VDA 5050 message:
the factsheet's idLen and enumLen. Ids make task ids, `<orderId>/<nodeId>/<sequenceId>` the
longest (100 + 1 + 100 + 1 + 10 characters): within TEXT_MAX_CHARACTERS."""
VDA5050_TEXT_MAX_CHARACTERS = 1000
"""Any other string of a VDA 5050 message (a description, a parameter's value)."""
VDA5050_LIST_MAX = 1000
"""The nodes and the edges of an order, the points of a trajectory, and the items of any
other list of a VDA 5050 message but those of VDA5050_ACTIONS_MAX."""
VDA5050_ACTIONS_MAX = 100
"""The actions of a node, of an edge or of an instantActions message; the parameters of an
action."""
VDA5050_UINT32 = NumberBound(0, 2**32 - 1)
"""headerId, orderUpdateId and sequenceId: the standard's uint32."""
VDA5050_NUMBER = NumberBound(-(2**53), 2**53)
"""Any other number of a VDA 5050 message (float64 in the standard): at most 2^53 (9e15) either
way, what a float64 holds exactly, far beyond any distance, speed or angle."""
VDA5050_UPDATES_WAITING_MAX = 10
"""Order updates waiting for the running base of their order to end; one more is refused."""
VDA5050_WAITING_MAX_BYTES = 16_777_216
"""The inbound VDA 5050 messages received and not yet handled, in bytes; more are dropped (and
counted in state) until the adapter has caught up."""
VDA5050_STATE_ERRORS_MAX = 20
"""The errors a VDA 5050 state shows, the newest, one of them saying how many older ones were
left out."""
VDA5050_STATE_ACTIONS_MAX = 1000
"""The actionStates a VDA 5050 vehicle keeps: beyond it the oldest ended ones are forgotten, and
state shows the first ones not ended with a note of how many were left out."""
VDA5050_INSTANT_ACTIONS_KEPT = 50
"""Instant actions kept in a VDA 5050 state's actionStates: the oldest ended ones beyond go."""
VDA5050_RESULT_DESCRIPTION_MAX_CHARACTERS = 500
"""An action's resultDescription in a VDA 5050 state (its task's result or error), cut beyond."""


def task_data_problem(task_data: str) -> str:
    """Why a request's task_data is too large; empty when it is not."""
    if len(task_data) * 4 <= TASK_DATA_MAX_BYTES:  # at most 4 bytes a character: no need to count
        return ''
    if (size := len(task_data.encode(errors='surrogatepass'))) > TASK_DATA_MAX_BYTES:
        return f'task_data is {size} bytes; at most {TASK_DATA_MAX_BYTES} are allowed'
    return ''


def ids_problem(field: str, ids: list[str]) -> str:
    """Why a list of task ids may not be `field`: more than IDS_MAX, or one given twice (each
    one would act, and be recorded, again); empty when it may."""
    if len(ids) > IDS_MAX:
        return f'{field} has {len(ids)} ids; at most {IDS_MAX} are allowed'
    return duplicate_problem(field, ids)


def duplicate_problem(field: str, ids: list[str]) -> str:
    """Why a list of ids may not be `field` (an id given twice); empty when it may."""
    seen: set[str] = set()
    for task_id in ids:
        if task_id in seen:
            return f'{field} names {cut_text(task_id)!r} more than once; each id at most once'
        seen.add(task_id)
    return ''


def cut_text(text: str, limit: int = ECHO_MAX_CHARACTERS) -> str:
    """`text`, or its first `limit` characters and a note of how many were left out."""
    if len(text) <= limit:
        return text
    return f'{text[:limit]}… ({len(text) - limit} more characters)'
