"""The vehicle's state as VDA 5050 reports it, kept up to date by the adapter (pure).

Action states come from the statuses of the tasks that carry the actions out:
RECEIVED and QUEUED -> WAITING (INITIALIZING once the Task Manager has the request),
IN_PROGRESS -> RUNNING, PAUSED -> PAUSED, DONE -> FINISHED, ERROR and CANCELED -> FAILED.

What it keeps is bounded (core/bounds.py): the newest VDA5050_STATE_ERRORS_MAX errors, each
echoing at most a cut of what it is about; VDA5050_STATE_ACTIONS_MAX actions (the oldest ended
ones forgotten beyond). A list cut short says so in the standard's terms: an error
`errorsLeftOut`, an information `actionStatesLeftOut`, each with the count left out.
"""

import copy
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from task_manager.core.bounds import (
    REASON_MAX_CHARACTERS,
    VDA5050_INSTANT_ACTIONS_KEPT,
    VDA5050_STATE_ACTIONS_MAX,
    VDA5050_STATE_ERRORS_MAX,
    cut_text,
)
from task_manager_vda5050.orders.plan import Rejection

ACTION_STATUS = {
    'RECEIVED': 'INITIALIZING',
    'QUEUED': 'WAITING',
    'IN_PROGRESS': 'RUNNING',
    'PAUSED': 'PAUSED',
    'DONE': 'FINISHED',
    'ERROR': 'FAILED',
    'CANCELED': 'FAILED',
}
ENDED = ('FINISHED', 'FAILED')
ERRORS_LEFT_OUT = 'errorsLeftOut'
"""The errorType of the error saying how many older errors state leaves out."""
ACTION_STATES_LEFT_OUT = 'actionStatesLeftOut'
"""The infoType of the information saying how many actionStates state leaves out."""


@dataclass
class Position:
    x: float
    y: float
    theta: float
    map_id: str


@dataclass
class VehicleState:
    """What state reports, but the header."""

    order_id: str = ''
    order_update_id: int = 0
    last_node_id: str = ''
    last_node_sequence_id: int = 0
    node_states: list[dict[str, Any]] = field(default_factory=list)
    edge_states: list[dict[str, Any]] = field(default_factory=list)
    # key: actionId, value: its actionState (in the order they came)
    action_states: dict[str, dict[str, Any]] = field(default_factory=dict)
    driving: bool = False
    paused: bool = False
    errors: list[dict[str, Any]] = field(default_factory=list)
    """The newest VDA5050_STATE_ERRORS_MAX."""
    # key: errorType, value: how many of its errors, older than those kept, were left out
    errors_left_out: Counter[str] = field(default_factory=Counter)
    information: list[dict[str, Any]] = field(default_factory=list)
    position: Position | None = None
    battery: dict[str, Any] = field(
        default_factory=lambda: {'batteryCharge': 100.0, 'charging': False}
    )
    safety: dict[str, Any] = field(
        default_factory=lambda: {'eStop': 'NONE', 'fieldViolation': False}
    )
    operating_mode: str = 'AUTOMATIC'

    def take_order(self, order: dict[str, Any], stitched: bool) -> None:
        """A new order or update taken: its nodes and edges still to pass, its actions
        WAITING (the first node of an update was passed already)."""
        first = min(order['nodes'], key=lambda n: n['sequenceId'])
        if order['orderId'] != self.order_id:
            self.action_states = {k: v for k, v in self.action_states.items() if v.get('_instant')}
        self.order_id, self.order_update_id = order['orderId'], order['orderUpdateId']
        self.node_states = [_node_state(n) for n in order['nodes'] if not (stitched and n is first)]
        self.edge_states = [_edge_state(e) for e in order['edges']]
        for item in (*order['nodes'], *order['edges']):
            if stitched and item is first:
                continue
            for action in item['actions'] if item.get('released') else ():
                self.action_states.setdefault(action['actionId'], _action_state(action))
        self._forget_ended_actions()
        self.clear_errors(_ORDER_ERRORS)

    def node_reached(self, node_id: str, sequence_id: int) -> None:
        """The node and the edge before it are passed."""
        self.last_node_id, self.last_node_sequence_id = node_id, sequence_id
        self.node_states = [n for n in self.node_states if n['sequenceId'] > sequence_id]
        self.edge_states = [e for e in self.edge_states if e['sequenceId'] > sequence_id]

    def add_instant(self, action: dict[str, Any]) -> None:
        """An instant action, WAITING; the oldest ended ones beyond
        VDA5050_INSTANT_ACTIONS_KEPT go."""
        self.action_states[action['actionId']] = {**_action_state(action), '_instant': True}
        instant = [k for k, v in self.action_states.items() if v.get('_instant')]
        for action_id in instant[: max(len(instant) - VDA5050_INSTANT_ACTIONS_KEPT, 0)]:
            if self.action_states[action_id]['actionStatus'] in ENDED:
                del self.action_states[action_id]
        self._forget_ended_actions()

    def _forget_ended_actions(self) -> None:
        """Beyond VDA5050_STATE_ACTIONS_MAX actions, the oldest ended ones are forgotten."""
        excess = len(self.action_states) - VDA5050_STATE_ACTIONS_MAX
        if excess <= 0:
            return
        ended = [k for k, v in self.action_states.items() if v['actionStatus'] in ENDED]
        for action_id in ended[:excess]:
            del self.action_states[action_id]

    def action_ids_in_use(self, same_order: bool) -> set[str]:
        """The actionIds a new order (`same_order`: an update of the current one) may not
        use: the instant actions' and, for an update, its order's."""
        return {k for k, v in self.action_states.items() if same_order or v.get('_instant')}

    def set_action(self, action_id: str, status: str, description: str = '') -> bool:
        """An action's new status (an actionStatus); whether anything changed. An ended
        action's status stays."""
        state = self.action_states.get(action_id)
        if state is None or state['actionStatus'] in ENDED:
            return False
        changed = bool(state['actionStatus'] != status)
        state['actionStatus'] = status
        if description and state.get('resultDescription') != description:
            state['resultDescription'] = description
            changed = True
        return changed

    def action_status(self, action_id: str) -> str:
        state = self.action_states.get(action_id)
        return '' if state is None else str(state['actionStatus'])

    def add_error(self, rejection: Rejection, level: str = 'WARNING') -> None:
        """An error, its description and references cut (they may echo what a master sent);
        the oldest beyond VDA5050_STATE_ERRORS_MAX go, counted."""
        error: dict[str, Any] = {
            'errorType': rejection.error_type,
            'errorLevel': level,
            'errorDescription': cut_text(rejection.description, REASON_MAX_CHARACTERS),
        }
        if rejection.references:
            error['errorReferences'] = [
                {'referenceKey': key, 'referenceValue': cut_text(value)}
                for key, value in rejection.references
            ]
        self.errors.append(error)
        while len(self.errors) > VDA5050_STATE_ERRORS_MAX:
            self.errors_left_out[self.errors.pop(0)['errorType']] += 1

    def clear_errors(self, error_types: tuple[str, ...]) -> None:
        """The errors of these types are over (those left out too)."""
        self.errors = [e for e in self.errors if e['errorType'] not in error_types]
        for error_type in error_types:
            self.errors_left_out.pop(error_type, None)

    def document(self) -> dict[str, Any]:
        """The state's fields, without the header."""
        document: dict[str, Any] = {
            'orderId': self.order_id,
            'orderUpdateId': self.order_update_id,
            'lastNodeId': self.last_node_id,
            'lastNodeSequenceId': self.last_node_sequence_id,
            'nodeStates': copy.deepcopy(self.node_states),
            'edgeStates': copy.deepcopy(self.edge_states),
            'driving': self.driving,
            'paused': self.paused,
            'newBaseRequest': False,
            'operatingMode': self.operating_mode,
            'actionStates': [
                {k: v for k, v in state.items() if not k.startswith('_')}
                for state in list(self.action_states.values())[:VDA5050_STATE_ACTIONS_MAX]
            ],
            'batteryState': dict(self.battery),
            'errors': self._errors_shown(),
            'information': [*copy.deepcopy(self.information), *self._actions_left_out()],
            'safetyState': dict(self.safety),
        }
        if self.position is not None:
            document['agvPosition'] = {
                'x': self.position.x,
                'y': self.position.y,
                'theta': self.position.theta,
                'mapId': self.position.map_id,
                'positionInitialized': True,
            }
        return document

    def _errors_shown(self) -> list[dict[str, Any]]:
        """The errors kept; when some were left out, the newest but one and an error saying
        how many were left out."""
        left_out = sum(self.errors_left_out.values())
        if not left_out:
            return copy.deepcopy(self.errors)
        shown = self.errors[len(self.errors) - VDA5050_STATE_ERRORS_MAX + 1 :]
        left_out += len(self.errors) - len(shown)
        note = {
            'errorType': ERRORS_LEFT_OUT,
            'errorLevel': 'WARNING',
            'errorDescription': f'{left_out} older errors left out: '
            f'state shows the newest {len(shown)}',
            'errorReferences': [{'referenceKey': 'leftOut', 'referenceValue': str(left_out)}],
        }
        return [note, *copy.deepcopy(shown)]

    def _actions_left_out(self) -> list[dict[str, Any]]:
        """An information saying how many actionStates state leaves out, if it leaves any."""
        left_out = len(self.action_states) - VDA5050_STATE_ACTIONS_MAX
        if left_out <= 0:
            return []
        return [
            {
                'infoType': ACTION_STATES_LEFT_OUT,
                'infoLevel': 'INFO',
                'infoDescription': f'{left_out} actionStates left out, the newest: '
                f'state shows the first {VDA5050_STATE_ACTIONS_MAX}',
                'infoReferences': [{'referenceKey': 'leftOut', 'referenceValue': str(left_out)}],
            }
        ]


_ORDER_ERRORS = (
    'orderError',
    'orderUpdateError',
    'noRouteError',
    'validationError',
    'orderActionError',
)
"""Cleared when an order is taken: the master has sent one that works."""


def _node_state(node: dict[str, Any]) -> dict[str, Any]:
    state = {k: node[k] for k in ('nodeId', 'sequenceId', 'released')}
    if 'nodePosition' in node:
        state['nodePosition'] = node['nodePosition']
    if 'nodeDescription' in node:
        state['nodeDescription'] = node['nodeDescription']
    return state


def _edge_state(edge: dict[str, Any]) -> dict[str, Any]:
    state = {k: edge[k] for k in ('edgeId', 'sequenceId', 'released')}
    if 'edgeDescription' in edge:
        state['edgeDescription'] = edge['edgeDescription']
    return state


def _action_state(action: dict[str, Any]) -> dict[str, Any]:
    state = {
        'actionId': action['actionId'],
        'actionType': action['actionType'],
        'actionStatus': 'WAITING',
    }
    if action.get('actionDescription'):
        state['actionDescription'] = action['actionDescription']
    return state
