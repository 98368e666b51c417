"""Instant actions: pause and resume, cancelOrder, stateRequest, factsheetRequest, and the
mapped ones (tasks `instant/<actionId>`), each reported in state.actionStates."""

import logging
from collections.abc import Callable
from typing import Any

from task_manager.client import TaskEvent, TaskEventKind, TaskManagerClient
from task_manager.core.bounds import cut_text
from task_manager.core.errors import TaskManagerError
from task_manager_vda5050.mapping import Mapping, MissingValueError
from task_manager_vda5050.orders.plan import VALIDATION_ERROR, Rejection
from task_manager_vda5050.orders.running import SOURCE, Orders, description
from task_manager_vda5050.state.vehicle_state import ACTION_STATUS, VehicleState

LOG = logging.getLogger('task_manager_vda5050')
INSTANT_ACTION_ERROR = 'instantActionError'
NO_ORDER_TO_CANCEL = 'noOrderToCancel'


class InstantActions:
    def __init__(
        self,
        client: TaskManagerClient,
        mapping: Mapping,
        state: VehicleState,
        orders: Orders,
        publish: Callable[[str], None],
    ) -> None:
        """`publish(topic)`: send the state or the factsheet now."""
        self.client = client
        self.mapping = mapping
        self.state = state
        self.orders = orders
        self.publish = publish
        # key: task id, value: the actionId it carries out
        self.tasks: dict[str, str] = {}
        self._built_in: dict[str, Callable[[dict[str, Any]], str]] = {
            'startPause': self._start_pause,
            'stopPause': self._stop_pause,
            'cancelOrder': self._cancel_order,
            'stateRequest': lambda _: '',
            'factsheetRequest': self._factsheet,
        }

    def receive(self, message: dict[str, Any]) -> None:
        for action in message['actions']:
            self._run(action)

    def _run(self, action: dict[str, Any]) -> None:
        action_type, action_id = action['actionType'], action['actionId']
        if action_id in self.state.action_states:
            why = f'actionId {cut_text(action_id)!r} is in use already: each action needs its own'
            self._refuse(action, why, VALIDATION_ERROR)
            return
        built_in = self._built_in.get(action_type)
        if built_in is None and self.mapping.action(action_type, 'INSTANT') is None:
            self._refuse(action, f'instant action type {cut_text(action_type)!r} is not supported')
            return
        self.state.add_instant(action)
        if built_in is None:
            self._start_mapped(action)
            return
        self.state.set_action(action_id, 'RUNNING')
        why_not = built_in(action)
        self.state.set_action(action_id, 'FAILED' if why_not else 'FINISHED', why_not)
        if action_type == 'stateRequest':
            self.publish('state')

    def _refuse(
        self, action: dict[str, Any], why: str, error_type: str = INSTANT_ACTION_ERROR
    ) -> None:
        LOG.warning('instant action %s: %s', cut_text(action['actionId']), why)
        self.state.add_error(
            Rejection(
                error_type,
                why,
                (
                    ('topic', 'instantActions'),
                    ('actionId', action['actionId']),
                    ('actionType', action['actionType']),
                ),
            )
        )

    def _start_pause(self, _: dict[str, Any]) -> str:
        if self.orders.mission_id:
            result = self.client.pause([self.orders.mission_id], source=SOURCE)
            if not result.ok:
                return f'not paused: {result.result.get("errors") or result.error_message}'
        self.state.paused = True
        self.state.driving = False
        return ''

    def _stop_pause(self, _: dict[str, Any]) -> str:
        if self.orders.mission_id and self.state.paused:
            result = self.client.resume([self.orders.mission_id], source=SOURCE)
            if not result.ok:
                return f'not resumed: {result.result.get("errors") or result.error_message}'
        self.state.paused = False
        return ''

    def _cancel_order(self, action: dict[str, Any]) -> str:
        if not self.orders.active:
            why = 'no order to cancel'
            self._refuse(action, why, NO_ORDER_TO_CANCEL)
            return why
        return self.orders.cancel()

    def _factsheet(self, _: dict[str, Any]) -> str:
        self.publish('factsheet')
        return ''

    def _start_mapped(self, action: dict[str, Any]) -> None:
        mapped = self.mapping.action(action['actionType'], 'INSTANT')
        assert mapped is not None
        values = {p['key']: p['value'] for p in action.get('actionParameters') or []}
        task_id = f'instant/{action["actionId"]}'
        try:
            data = mapped.data(values)
            self.tasks[task_id] = action['actionId']
            self.client.start_task(mapped.task_name, data, task_id=task_id, source=SOURCE)
        except MissingValueError as missing:
            self.state.set_action(
                action['actionId'], 'FAILED', f'the parameter {missing.args[0]!r} is required'
            )
        except (TaskManagerError, ValueError) as error:
            self.state.set_action(action['actionId'], 'FAILED', f'not started: {error}')

    def followed(self) -> list[str]:
        """The ids of the instant actions' tasks that have not ended here."""
        return list(self.tasks)

    def on_event(self, event: TaskEvent) -> None:
        action_id = self.tasks.get(event.task.task_id)
        if action_id is None:
            return
        ended = event.kind is TaskEventKind.ENDED
        status = ACTION_STATUS.get(str(event.task.status), 'WAITING')
        self.state.set_action(action_id, status, description(event.task) if ended else '')
        if ended:
            del self.tasks[event.task.task_id]
