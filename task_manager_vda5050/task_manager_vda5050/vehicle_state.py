"""The vehicle's state as VDA 5050 reports it, kept up to date by the adapter (pure).

Action states come from the statuses of the tasks that carry the actions out:
RECEIVED and QUEUED -> WAITING (INITIALIZING once the Task Manager has the request),
IN_PROGRESS -> RUNNING, PAUSED -> PAUSED, DONE -> FINISHED, ERROR and CANCELED -> FAILED.
"""

import copy
from dataclasses import dataclass, field
from typing import Any

from task_manager_vda5050.order_plan import Rejection

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
MAX_ERRORS = 20
MAX_INSTANT = 50
"""Instant actions kept in actionStates (until a new order clears the order's)."""
"""The errors kept in state (the oldest go first): a master sending bad messages in a loop
must not grow the state without end."""


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
        self.errors = [e for e in self.errors if e['errorType'] not in _ORDER_ERRORS]

    def node_reached(self, node_id: str, sequence_id: int) -> None:
        """The node and the edge before it are passed."""
        self.last_node_id, self.last_node_sequence_id = node_id, sequence_id
        self.node_states = [n for n in self.node_states if n['sequenceId'] > sequence_id]
        self.edge_states = [e for e in self.edge_states if e['sequenceId'] > sequence_id]

    def add_instant(self, action: dict[str, Any]) -> None:
        """An instant action, WAITING; the oldest ended ones beyond MAX_INSTANT go."""
        self.action_states[action['actionId']] = {**_action_state(action), '_instant': True}
        instant = [k for k, v in self.action_states.items() if v.get('_instant')]
        for action_id in instant[: max(len(instant) - MAX_INSTANT, 0)]:
            if self.action_states[action_id]['actionStatus'] in ENDED:
                del self.action_states[action_id]

    def set_action(self, action_id: str, status: str, description: str = '') -> bool:
        """An action's new status (an actionStatus); whether anything changed. An ended
        action's status stays."""
        state = self.action_states.get(action_id)
        if state is None or state['actionStatus'] in ENDED:
            return False
        changed = state['actionStatus'] != status
        state['actionStatus'] = status
        if description and state.get('resultDescription') != description:
            state['resultDescription'] = description
            changed = True
        return changed

    def action_status(self, action_id: str) -> str:
        state = self.action_states.get(action_id)
        return '' if state is None else str(state['actionStatus'])

    def add_error(self, rejection: Rejection, level: str = 'WARNING') -> None:
        error: dict[str, Any] = {
            'errorType': rejection.error_type,
            'errorLevel': level,
            'errorDescription': rejection.description,
        }
        if rejection.references:
            error['errorReferences'] = [
                {'referenceKey': key, 'referenceValue': value}
                for key, value in rejection.references
            ]
        self.errors = [*self.errors, error][-MAX_ERRORS:]

    def clear_errors(self, error_types: tuple[str, ...]) -> None:
        self.errors = [e for e in self.errors if e['errorType'] not in error_types]

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
                for state in self.action_states.values()
            ],
            'batteryState': dict(self.battery),
            'errors': copy.deepcopy(self.errors),
            'information': copy.deepcopy(self.information),
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
