"""An order (or an order update) checked and turned into the tasks that carry out its base.

Pure: no MQTT, no ROS. The released base of each order or update becomes one *segment*: one
Task Manager mission whose subtasks are, node after node, the drive to the node and its
HARD and SOFT actions (HARD and SOFT edge actions before the drive over their edge); actions
of blocking type NONE are tasks started beside the mission (a node's once it is reached, an
edge's once the drive over it starts). Horizon nodes and edges start nothing.
"""

from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from typing import Any

from task_manager.core.bounds import IDS_MAX
from task_manager_vda5050.mapping import Mapping, MissingValueError

ORDER_ERROR = 'orderError'
ORDER_UPDATE_ERROR = 'orderUpdateError'
VALIDATION_ERROR = 'validationError'
NO_ROUTE_ERROR = 'noRouteError'
POSITION_FIELDS = ('x', 'y', 'theta', 'mapId', 'allowedDeviationXY', 'allowedDeviationTheta')


@dataclass(frozen=True)
class Rejection:
    """Why an order is not taken: an error of state.errors."""

    error_type: str
    description: str
    references: tuple[tuple[str, str], ...] = ()


class OrderRejectedError(Exception):
    def __init__(self, rejection: Rejection) -> None:
        super().__init__(rejection.description)
        self.rejection = rejection


@dataclass(frozen=True)
class PlannedTask:
    """A task of the segment: a drive to a node (action_id '') or an action."""

    task_id: str
    task_name: str
    task_data: dict[str, Any]
    action_id: str = ''
    node_id: str = ''
    sequence_id: int = 0
    """The node's (a drive) or the node's or edge's the action is on."""


@dataclass
class Segment:
    """One released base of an order: its mission and the tasks started beside it."""

    order_id: str
    order_update_id: int
    mission_id: str
    steps: list[PlannedTask]
    after_reaching: dict[str, list[PlannedTask]] = field(default_factory=dict)
    """key: a drive's task id, value: the NONE actions started once it ends DONE."""
    while_driving: dict[str, list[PlannedTask]] = field(default_factory=dict)
    """key: a drive's task id, value: the NONE edge actions started when it starts."""
    last_base: tuple[str, int] = ('', 0)
    """The last base node (nodeId, sequenceId): where an update must start."""

    @property
    def beside(self) -> list[PlannedTask]:
        return [
            t
            for tasks in (*self.after_reaching.values(), *self.while_driving.values())
            for t in tasks
        ]


def references(order: dict[str, Any], *more: tuple[str, str]) -> tuple[tuple[str, str], ...]:
    """The references of an error about `order` (the topic, its header and ids, then
    `more`), as master controls match them to the order they sent."""
    return (
        ('topic', 'order'),
        ('headerId', str(order.get('headerId', ''))),
        ('orderId', str(order.get('orderId', ''))),
        ('orderUpdateId', str(order.get('orderUpdateId', ''))),
        *more,
    )


def _reject(error_type: str, order: dict[str, Any], what: str, *more: tuple[str, str]) -> None:
    raise OrderRejectedError(Rejection(error_type, what, references(order, *more)))


def check_graph(order: dict[str, Any]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The base nodes and edges, in order; validationError when the graph is inconsistent."""
    nodes = sorted(order['nodes'], key=lambda n: n['sequenceId'])
    edges = sorted(order['edges'], key=lambda e: e['sequenceId'])
    if not nodes:
        _reject(VALIDATION_ERROR, order, 'an order needs at least one node')
    if len(edges) != len(nodes) - 1:
        _reject(
            VALIDATION_ERROR,
            order,
            f'{len(nodes)} nodes need {len(nodes) - 1} edges, got {len(edges)}',
        )
    for index, edge in enumerate(edges):
        start, end = nodes[index], nodes[index + 1]
        if (edge['startNodeId'], edge['endNodeId']) != (start['nodeId'], end['nodeId']) or not (
            start['sequenceId'] < edge['sequenceId'] < end['sequenceId']
        ):
            _reject(
                VALIDATION_ERROR,
                order,
                f'edge {edge["edgeId"]} does not join node '
                f'{start["nodeId"]} to node {end["nodeId"]} in sequence',
                ('edgeId', edge['edgeId']),
            )
    base = [n for n in nodes if n['released']]
    if not base or base != nodes[: len(base)]:
        _reject(VALIDATION_ERROR, order, 'the released nodes must come first, at least one')
    base_edges = [e for e in edges if e['released']]
    if base_edges != edges[: len(base) - 1]:
        _reject(VALIDATION_ERROR, order, 'the released edges must be those between base nodes')
    return base, base_edges


class Planner:
    """Checks orders against the mapping and plans their segments."""

    def __init__(self, mapping: Mapping, drives_or_blocks: Callable[[str], bool]) -> None:
        """`drives_or_blocks(task_name)`: whether a task cannot run beside driving (it holds
        the navigation's resources, or is blocking): it may not be of blocking type NONE."""
        self.mapping = mapping
        self.drives_or_blocks = drives_or_blocks

    def check_actions(self, order: dict[str, Any]) -> None:
        """orderError for the first action that no task carries out (nothing is started)."""
        for scope, key, items in (
            ('NODE', 'nodeId', order['nodes']),
            ('EDGE', 'edgeId', order['edges']),
        ):
            for item in items:
                for action in item['actions']:
                    self.task_of(order, action, scope, (key, item[key]))

    def task_of(
        self, order: dict[str, Any], action: dict[str, Any], scope: str, where: tuple[str, str]
    ) -> tuple[str, dict[str, Any]]:
        """An action's task name and data; orderError when it has none."""
        refs = (where, ('actionId', action['actionId']), ('actionType', action['actionType']))
        mapped = self.mapping.action(action['actionType'], scope)
        if mapped is None:
            _reject(
                ORDER_ERROR,
                order,
                f'action type {action["actionType"]!r} is not supported on a {scope.lower()}',
                *refs,
            )
            raise AssertionError  # unreachable: _reject raises
        if action['blockingType'] == 'NONE' and self.drives_or_blocks(mapped.task_name):
            _reject(
                ORDER_ERROR,
                order,
                f'action type {action["actionType"]!r} cannot run while '
                'driving: blocking type NONE is not possible',
                *refs,
            )
        values = {p['key']: p['value'] for p in action.get('actionParameters') or []}
        try:
            return mapped.task_name, mapped.data(values)
        except MissingValueError as missing:
            _reject(
                ORDER_ERROR,
                order,
                f'action {action["actionId"]} needs the parameter {missing.args[0]!r}',
                *refs,
                ('actionParameter', str(missing.args[0])),
            )
            raise AssertionError from None

    def plan(
        self,
        order: dict[str, Any],
        mission_id: str,
        stitched: bool,
        action_ids_in_use: Collection[str] = (),
        task_ids_in_use: Collection[str] = (),
    ) -> Segment:
        """The segment of an order's released base; `stitched`: its first node is the last
        one reached already (an update), so neither driven to nor its actions run again.
        The ids in use (by the order's earlier segments, by instant actions) may not be
        used again."""
        base, base_edges = check_graph(order)
        check_action_ids(order, stitched, action_ids_in_use)
        self.check_actions(order)
        segment = Segment(order['orderId'], order['orderUpdateId'], mission_id, [])
        segment.last_base = (base[-1]['nodeId'], base[-1]['sequenceId'])
        for index, node in enumerate(base):
            if index == 0 and stitched:
                continue
            edge = base_edges[index - 1] if index > 0 else None
            self._add_node(order, segment, node, edge)
        check_task_ids(order, segment, task_ids_in_use)
        return segment

    def _add_node(
        self,
        order: dict[str, Any],
        segment: Segment,
        node: dict[str, Any],
        edge: dict[str, Any] | None,
    ) -> None:
        beside_drive: list[PlannedTask] = []
        if edge is not None:
            for action in edge['actions']:
                task = self._action_task(order, segment, action, 'EDGE', edge)
                if action['blockingType'] == 'NONE':
                    beside_drive.append(task)
                else:
                    segment.steps.append(task)
        drive = self._drive(order, segment, node, needed=edge is not None)
        if drive is not None:
            segment.steps.append(drive)
            if beside_drive:
                segment.while_driving[drive.task_id] = beside_drive
        else:
            segment.steps += beside_drive
        for action in node['actions']:
            task = self._action_task(order, segment, action, 'NODE', node)
            if action['blockingType'] == 'NONE' and drive is not None:
                segment.after_reaching.setdefault(drive.task_id, []).append(task)
            else:
                segment.steps.append(task)

    def _drive(
        self, order: dict[str, Any], segment: Segment, node: dict[str, Any], needed: bool
    ) -> PlannedTask | None:
        """The drive to `node`; None for an order's first node without a position (the
        vehicle is on it). noRouteError for another node without one."""
        position = node.get('nodePosition')
        if position is None:
            if needed:
                _reject(
                    NO_ROUTE_ERROR,
                    order,
                    f'node {node["nodeId"]} has no nodePosition: no route to it',
                    ('nodeId', node['nodeId']),
                )
            return None
        values = {k: position[k] for k in POSITION_FIELDS if k in position}
        try:
            data = self.mapping.navigation.data(values)
        except MissingValueError as missing:
            _reject(
                NO_ROUTE_ERROR,
                order,
                f'node {node["nodeId"]}: its nodePosition has no {missing.args[0]}',
                ('nodeId', node['nodeId']),
            )
            raise AssertionError from None
        return PlannedTask(
            f'{segment.order_id}/{node["nodeId"]}/{node["sequenceId"]}',
            self.mapping.navigation.task_name,
            data,
            node_id=node['nodeId'],
            sequence_id=node['sequenceId'],
        )

    def _action_task(
        self,
        order: dict[str, Any],
        segment: Segment,
        action: dict[str, Any],
        scope: str,
        item: dict[str, Any],
    ) -> PlannedTask:
        key = 'nodeId' if scope == 'NODE' else 'edgeId'
        task_name, data = self.task_of(order, action, scope, (key, item[key]))
        return PlannedTask(
            f'{segment.order_id}/{action["actionId"]}',
            task_name,
            data,
            action_id=action['actionId'],
            node_id=item[key],
            sequence_id=item['sequenceId'],
        )


def check_action_ids(order: dict[str, Any], stitched: bool, in_use: Collection[str] = ()) -> None:
    """validationError for an actionId given twice in `order`, or one `in_use` (the first
    node of an update, `stitched`, repeats the actions of the node it starts at: not new)."""
    first = min(order['nodes'], key=lambda n: n['sequenceId'], default=None)
    seen: set[str] = set()
    for item in (*order['nodes'], *order['edges']):
        if stitched and item is first:
            continue
        for action in item['actions']:
            action_id = action['actionId']
            if action_id in seen or action_id in in_use:
                where = 'in this order' if action_id in seen else 'already'
                _reject(
                    VALIDATION_ERROR,
                    order,
                    f'actionId {action_id!r} is used {where}: each action needs an id of its own',
                    ('actionId', action_id),
                )
            seen.add(action_id)


def check_task_ids(order: dict[str, Any], segment: Segment, in_use: Collection[str] = ()) -> None:
    """validationError when two tasks of the segment, or one and a task `in_use`, would have
    the same id (an action `<orderId>/<actionId>`, a drive `<orderId>/<nodeId>/<sequenceId>`:
    actionId 'b/2' is the drive to node b of sequenceId 2), or the segment has more tasks
    than a mission may (IDS_MAX)."""
    tasks = [*segment.steps, *segment.beside]
    if len(tasks) > IDS_MAX:
        _reject(
            VALIDATION_ERROR,
            order,
            f'the released base makes {len(tasks)} tasks (drives and actions); '
            f'at most {IDS_MAX} in one order or update',
        )
    taken = {*in_use, segment.mission_id}
    drives = [t for t in tasks if not t.action_id]
    for drive in drives:
        if drive.task_id in taken:
            _reject(
                VALIDATION_ERROR,
                order,
                f'the drive to node {drive.node_id} would be the task {drive.task_id!r}, '
                'which the order has already',
                ('nodeId', drive.node_id),
            )
    taken |= {drive.task_id for drive in drives}
    for action in (t for t in tasks if t.action_id):
        if action.task_id in taken:
            _reject(
                VALIDATION_ERROR,
                order,
                f'actionId {action.action_id!r} would make the task {action.task_id!r}, '
                'which the order has already (an actionId "<nodeId>/<sequenceId>" is the '
                "drive's to that node)",
                ('actionId', action.action_id),
            )


def check_update(
    order: dict[str, Any], current_id: str, current_update_id: int, last_base: tuple[str, int]
) -> bool:
    """Whether `order` (same orderId as the current one) is a new update to take (False: the
    same update again, to ignore); orderUpdateError when stale or not starting where the
    current base ends."""
    if order['orderUpdateId'] == current_update_id:
        return False
    if order['orderUpdateId'] < current_update_id:
        _reject(
            ORDER_UPDATE_ERROR,
            order,
            f'orderUpdateId {order["orderUpdateId"]} is older '
            f'than {current_update_id}, the order {current_id} has already',
        )
    first = min(order['nodes'], key=lambda n: n['sequenceId'], default=None)
    if first is None or (first['nodeId'], first['sequenceId']) != last_base:
        _reject(
            ORDER_UPDATE_ERROR,
            order,
            'an update must start at the last base node '
            f'{last_base[0]} (sequenceId {last_base[1]})',
            ('nodeId', '' if first is None else first['nodeId']),
        )
    return True
