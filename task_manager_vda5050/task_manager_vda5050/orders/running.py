"""Orders carried out through the Task Manager, and their progress read from its task events.

Each released base (an order, then each update) is one mission, `<orderId>` for the order
and `<orderId>/update/<orderUpdateId>` for an update, started when the one before it has
ended DONE (the adapter chains them: an update never runs before the base it extends). Its
subtasks are `<orderId>/<nodeId>/<sequenceId>` (the drive to a node) and
`<orderId>/<actionId>` (an action); NONE actions are tasks of those ids beside the mission.
All run on the worker thread of the adapter (adapter.py), which owns the state.
"""

import json
import logging
from typing import Any

from task_manager.client import Subtask, TaskEvent, TaskEventKind, TaskManagerClient
from task_manager.core.bounds import (
    VDA5050_RESULT_DESCRIPTION_MAX_CHARACTERS,
    VDA5050_UPDATES_WAITING_MAX,
    cut_text,
)
from task_manager.core.errors import TaskManagerError
from task_manager.core.status import TaskStatus
from task_manager_vda5050.mapping import PositionSource
from task_manager_vda5050.orders.plan import (
    ORDER_UPDATE_ERROR,
    OrderRejectedError,
    PlannedTask,
    Planner,
    Rejection,
    Segment,
    check_update,
    references,
)
from task_manager_vda5050.state.vehicle_state import ACTION_STATUS, Position, VehicleState

LOG = logging.getLogger('task_manager_vda5050')
SOURCE = 'VDA5050'
ORDER_ACTION_ERROR = 'orderActionError'


def description(task: Any) -> str:
    """A task's end in words for resultDescription: its error, or its result."""
    if task.status is TaskStatus.DONE:
        text = json.dumps(task.result or {}, sort_keys=True)
    else:
        error = (task.result or {}).get('error') if isinstance(task.result, dict) else ''
        text = f'{task.status}: {error or task.error_code}'
    return cut_text(text, VDA5050_RESULT_DESCRIPTION_MAX_CHARACTERS)


class Orders:
    def __init__(
        self,
        client: TaskManagerClient,
        planner: Planner,
        state: VehicleState,
        position: PositionSource | None,
    ) -> None:
        self.client = client
        self.planner = planner
        self.state = state
        self.position_source = position
        self.pending: list[Segment] = []
        self.running: Segment | None = None
        # key: task id, value: the planned task (drives and actions of every segment taken)
        self.tasks: dict[str, PlannedTask] = {}
        self.beside_active: set[str] = set()
        self._ended: set[str] = set()
        """The ids of the planned tasks that have ended."""
        self._started_steps: list[str] = []
        """The ids of the steps of the order's missions started, in the order they run."""
        self._reached = -1
        """The sequenceId of the order's last node reached."""
        self.last_base: tuple[str, int] = ('', 0)
        self._started_beside: set[str] = set()
        self._mission_ids: set[str] = set()
        """The missions of the current order (its base and each update)."""
        if position is not None and position.initial is not None:
            pose = position.initial
            state.position = Position(pose['x'], pose['y'], pose['theta'], position.map_id)

    @property
    def active(self) -> bool:
        """Whether the order has work left: a master may send the next order as soon as
        state shows every node passed and every action ended, before the mission's own end
        has reached the adapter. (The subtasks run in turn: the last one ended, all have.)"""
        running = self.running is not None and (
            not self.running.steps or self.running.steps[-1].task_id not in self._ended
        )
        return running or bool(self.pending) or bool(self.beside_active)

    # ---- receiving -----------------------------------------------------------------------

    def receive(self, order: dict[str, Any]) -> None:
        """Take an order or update, or leave it (the same one again); OrderRejectedError says why
        not, before anything moves."""
        same_order = order['orderId'] == self.state.order_id
        stitched = False
        if same_order:
            if not check_update(
                order, self.state.order_id, self.state.order_update_id, self.last_base
            ):
                LOG.info(
                    'order %s update %s again: ignored', order['orderId'], order['orderUpdateId']
                )
                return
            if len(self.pending) >= VDA5050_UPDATES_WAITING_MAX:
                raise OrderRejectedError(
                    Rejection(
                        ORDER_UPDATE_ERROR,
                        f'{len(self.pending)} updates of order {order["orderId"]} wait for its '
                        f'running base to end; at most {VDA5050_UPDATES_WAITING_MAX} may wait',
                        references(order),
                    )
                )
            stitched = True
        elif self.active:
            raise OrderRejectedError(
                Rejection(
                    ORDER_UPDATE_ERROR,
                    f'order {self.state.order_id} is still running: a new order waits for its end',
                    references(order),
                )
            )
        mission_id = (
            f'{order["orderId"]}/update/{order["orderUpdateId"]}' if stitched else order['orderId']
        )
        segment = self.planner.plan(
            order,
            mission_id,
            stitched,
            self.state.action_ids_in_use(same_order=stitched),
            {*self.tasks, *self._mission_ids} if stitched else (),
        )
        if not stitched:  # the order before has no work left: forget it
            self.running = None  # its mission's end is not awaited
            self.tasks, self._ended, self._started_beside = {}, set(), set()
            self._mission_ids, self._started_steps, self._reached = set(), [], -1
        self._mission_ids.add(mission_id)
        self.state.take_order(order, stitched)
        self.last_base = segment.last_base
        for task in (*segment.steps, *segment.beside):
            self.tasks[task.task_id] = task
        self.pending.append(segment)
        LOG.info(
            'order %s update %s taken: %d tasks in mission %s, %d beside',
            order['orderId'],
            order['orderUpdateId'],
            len(segment.steps),
            mission_id,
            len(segment.beside),
        )
        if self.running is None:
            self._start_next()

    def _start_next(self) -> None:
        while self.pending and self.running is None:
            segment = self.pending.pop(0)
            if not segment.steps:
                continue
            subtasks = [Subtask(t.task_name, t.task_data, task_id=t.task_id) for t in segment.steps]
            try:
                self.client.start_mission(subtasks, task_id=segment.mission_id, source=SOURCE)
            except (TaskManagerError, ValueError) as error:
                self._failed(segment, f'the Task Manager did not take the mission: {error}')
                continue
            self.running = segment
            self._started_steps.extend(t.task_id for t in segment.steps)
            if self.state.paused:
                self.client.pause([segment.mission_id], source=SOURCE)

    # ---- progress ------------------------------------------------------------------------

    def followed(self) -> list[str]:
        """The ids of the order's tasks the Task Manager has and that have not ended here, in
        the order their events come: the steps, the tasks beside, the running mission."""
        steps = [task_id for task_id in self._started_steps if task_id not in self._ended]
        mission = [self.running.mission_id] if self.running is not None else []
        return [*steps, *sorted(self.beside_active), *mission]

    def on_event(self, event: TaskEvent) -> None:
        task_state = event.task
        task_id = task_state.task_id
        if self.running is not None and task_id == self.running.mission_id:
            if event.kind is TaskEventKind.ENDED:
                self._mission_ended(self.running, task_state)
            return
        planned = self.tasks.get(task_id)
        if planned is None or task_id in self._ended:  # (an event read again after its end)
            return
        if planned.action_id:
            status = ACTION_STATUS.get(str(task_state.status), 'WAITING')
            ended = event.kind is TaskEventKind.ENDED
            self.state.set_action(
                planned.action_id, status, description(task_state) if ended else ''
            )
        else:
            self._drive_event(event, planned)
        if event.kind is TaskEventKind.ENDED:
            self.beside_active.discard(task_id)
            self._ended.add(task_id)

    def _drive_event(self, event: TaskEvent, drive: PlannedTask) -> None:
        kind = event.kind
        if kind in (TaskEventKind.STARTED, TaskEventKind.RESUMED):
            self.state.driving = True
            self._start_beside(self.running.while_driving if self.running else {}, drive.task_id)
        elif kind is TaskEventKind.PAUSED:
            self.state.driving = False
        elif kind is TaskEventKind.FEEDBACK:
            self._move(event.task.feedback)
        elif kind is TaskEventKind.ENDED:
            self.state.driving = False
            if event.task.status is not TaskStatus.DONE:
                return
            after_reaching = self.running.after_reaching if self.running else {}
            if drive.sequence_id > self._reached:
                self._reached = drive.sequence_id
                self._move(event.task.result)
                self.state.node_reached(drive.node_id, drive.sequence_id)
                self._start_beside(after_reaching, drive.task_id)
            else:  # a drive before the last node reached, its end learnt late
                self._not_started_late(after_reaching.get(drive.task_id, []), drive.node_id)

    def _not_started_late(self, tasks: list[PlannedTask], node_id: str) -> None:
        """The actions to start on reaching `node_id`, whose reaching was learnt only after a
        later node's (its events lost): FAILED, not started where the vehicle no longer is."""
        for task in tasks:
            if task.task_id in self._started_beside:
                continue
            self._started_beside.add(task.task_id)
            self.state.set_action(
                task.action_id,
                'FAILED',
                f'not started: reaching node {node_id} was learnt after a later node '
                '(task events went missing), and the vehicle is no longer there',
            )

    def _move(self, values: dict[str, Any] | None) -> None:
        """agvPosition from a drive's feedback or result, as the mapping names its fields."""
        source = self.position_source
        if source is None or not values:
            return
        x, y = values.get(source.x), values.get(source.y)
        if not isinstance(x, int | float) or not isinstance(y, int | float):
            return
        theta = values.get(source.theta)
        if not isinstance(theta, int | float):
            theta = self.state.position.theta if self.state.position else 0.0
        self.state.position = Position(float(x), float(y), float(theta), source.map_id)

    def _start_beside(self, tasks: dict[str, list[PlannedTask]], drive_id: str) -> None:
        for task in tasks.get(drive_id, []):
            if task.task_id in self._started_beside:
                continue
            self._started_beside.add(task.task_id)
            try:
                self.client.start_task(
                    task.task_name, task.task_data, task_id=task.task_id, source=SOURCE
                )
                self.beside_active.add(task.task_id)
            except (TaskManagerError, ValueError) as error:
                self.state.set_action(task.action_id, 'FAILED', f'not started: {error}')

    def _mission_ended(self, segment: Segment, mission: Any) -> None:
        self.running = None
        if mission.status is TaskStatus.DONE:
            self._start_next()
            return
        why = f'mission {segment.mission_id} ended {description(mission)}'
        self._failed(segment, why)
        for pending in self.pending:
            self._failed(pending, why, error=False)
        self.pending.clear()

    def _failed(self, segment: Segment, why: str, error: bool = True) -> None:
        """The segment's order is over: what it had left FAILED, nothing left to pass."""
        LOG.warning('order %s: %s', segment.order_id, why)
        for task in (*segment.steps, *segment.beside):
            if task.action_id and task.task_id not in self.beside_active:
                self.state.set_action(
                    task.action_id,
                    'FAILED',
                    cut_text(why, VDA5050_RESULT_DESCRIPTION_MAX_CHARACTERS),
                )
        self.state.node_states, self.state.edge_states = [], []
        self.state.driving = False
        if error:
            self.state.add_error(
                Rejection(
                    ORDER_ACTION_ERROR,
                    cut_text(why, VDA5050_RESULT_DESCRIPTION_MAX_CHARACTERS),
                    (
                        ('topic', 'order'),
                        ('orderId', segment.order_id),
                        ('orderUpdateId', str(segment.order_update_id)),
                    ),
                )
            )

    # ---- instant actions on the order --------------------------------------------------------

    def cancel(self) -> str:
        """Cancel the order's tasks; '' when done, else why not."""
        ids = [*([self.running.mission_id] if self.running else []), *sorted(self.beside_active)]
        segments = [*([self.running] if self.running else []), *self.pending]
        self.pending.clear()
        if ids:
            result = self.client.cancel_tasks(ids, source=SOURCE)
            if not result.ok:
                return result.error_message or str(result.status)
        self.running = None
        self.beside_active.clear()
        for segment in segments:
            for task in (*segment.steps, *segment.beside):
                if task.action_id:
                    self.state.set_action(task.action_id, 'FAILED', 'cancelled by cancelOrder')
        self.state.node_states, self.state.edge_states = [], []
        self.state.driving = False
        return ''

    @property
    def mission_id(self) -> str:
        return self.running.mission_id if self.running else ''
