"""The bridge's answers to the cloud's requests: a Reply document for every message.

Whatever arrives gets exactly one reply: invalid JSON, an unknown op or a missing field is
an `invalid_request` naming the field; a message over the size limit `payload_too_large`;
no Task Manager `task_manager_unavailable`. A start whose task id the Task Manager already
knows starts nothing: the reply is that task, with `duplicate: true`.
"""

import json
import logging
from typing import Any

from pydantic import ValidationError

from task_manager.client import Subtask, TaskHandle, TaskManagerClient, TaskState
from task_manager.core.errors import TaskManagerUnavailable
from task_manager.protocol import models
from task_manager.protocol.errors import describe
from task_manager.protocol.records import result_json, task_json

LOG = logging.getLogger('task_manager_mqtt')
OPS = ('start_task', 'start_mission', 'cancel', 'stop', 'history')


class RequestError(Exception):
    def __init__(self, code: str, message: str, field: str = '') -> None:
        super().__init__(message)
        self.detail = {'code': code, 'message': message, 'field': field}


class RequestHandler:
    """Runs each request through the Task Manager client (blocking: call it from a worker)."""

    def __init__(self, client: TaskManagerClient, source: str, max_payload_bytes: int) -> None:
        self.client = client
        self.source = source
        self.max_payload_bytes = max_payload_bytes

    def reply(self, payload: bytes) -> dict[str, Any]:
        """The Reply document to the request message `payload` (every field present)."""
        return models.Reply.model_validate(self._reply(payload)).model_dump(mode='json')

    def _reply(self, payload: bytes) -> dict[str, Any]:
        too_large = len(payload) > self.max_payload_bytes
        request_id, op = ('', '') if too_large else _ids_of(payload)
        try:
            request = self._parse(payload)
            return {'request_id': request_id, 'ok': True, 'op': op, **self._run(request)}
        except RequestError as error:
            LOG.warning('request %r (%s) refused: %s', request_id, op or '?', error)
            return {'request_id': request_id, 'ok': False, 'op': op, 'error': error.detail}
        except TaskManagerUnavailable as error:
            detail = {'code': 'task_manager_unavailable', 'message': str(error), 'field': ''}
            return {'request_id': request_id, 'ok': False, 'op': op, 'error': detail}
        except Exception as error:  # one line, a reply; the bridge goes on
            LOG.error('request %r (%s) failed: %s: %s', request_id, op, type(error).__name__, error)
            message = f'the bridge failed: {type(error).__name__}'
            detail = {'code': 'internal_error', 'message': message, 'field': ''}
            return {'request_id': request_id, 'ok': False, 'op': op, 'error': detail}

    def _parse(self, payload: bytes) -> Any:
        if len(payload) > self.max_payload_bytes:
            raise RequestError(
                'payload_too_large',
                f'the request is {len(payload)} bytes; at most {self.max_payload_bytes} allowed',
            )
        try:
            return models.RobotRequest.model_validate_json(payload).root
        except ValidationError as error:
            message, field = describe(error.errors(), skip=OPS)
            if error.errors()[0].get('type') == 'union_tag_invalid':
                message = f'unknown op; allowed: {", ".join(OPS)}'
                field = 'op'
            raise RequestError('invalid_request', message, field) from None

    def _run(self, request: Any) -> dict[str, Any]:
        if not self.client.connected:
            raise TaskManagerUnavailable(
                "the Task Manager is not reachable from the robot's bridge"
            )
        match request:
            case models.StartTaskRequest():
                return self._start_task(request)
            case models.StartMissionRequest():
                return self._start_mission(request)
            case models.CancelRequest():
                result = self.client.cancel_tasks(request.task_ids, source=self.source)
                return {'task': result_json(result)}
            case models.StopRequest():
                return {'task': result_json(self.client.stop(source=self.source))}
            case models.HistoryRequest():
                filters = request.model_dump(exclude={'request_id', 'op'})
                return {'tasks': [task_json(s) for s in self.client.history(**filters)]}
        raise AssertionError(f'unhandled request {request!r}')

    def _start_task(self, request: models.StartTaskRequest) -> dict[str, Any]:
        task_id = request.task_id or request.request_id
        if (known := self._known(task_id)) is not None:
            return known
        self.client.wait_until_available()
        handle = self.client.start_task(
            request.task_name,
            request.task_data,
            task_id=task_id,
            source=request.source or self.source,
        )
        return _started(handle)

    def _start_mission(self, request: models.StartMissionRequest) -> dict[str, Any]:
        task_id = request.task_id or request.request_id
        if (known := self._known(task_id)) is not None:
            return known
        subtasks = [
            Subtask(s.task_name, s.task_data, s.allow_skipping, s.task_id) for s in request.subtasks
        ]
        self.client.wait_until_available()
        handle, subtask_ids = self.client.start_mission(
            subtasks, task_id=task_id, source=request.source or self.source
        )
        return {**_started(handle), 'subtask_ids': subtask_ids}

    def _known(self, task_id: str) -> dict[str, Any] | None:
        """The reply to a start of a task id the Task Manager knows (active or ended)."""
        states = self.client.task_states([task_id])
        if not states:
            return None
        LOG.info('task %r is known already (a request delivered again?): nothing started', task_id)
        return {'task_id': task_id, 'duplicate': True, 'task': task_json(states[0])}


def _started(handle: TaskHandle) -> dict[str, Any]:
    state: TaskState | None = handle.state
    return {'task_id': handle.task_id, 'task': None if state is None else task_json(state)}


def _ids_of(payload: bytes) -> tuple[str, str]:
    """The request_id and op of a request, if it has them, for the reply to a bad one."""
    try:
        document = json.loads(payload)
    except ValueError:
        return '', ''
    if not isinstance(document, dict):
        return '', ''
    request_id, op = document.get('request_id'), document.get('op')
    return (
        request_id if isinstance(request_id, str) else '',
        op if isinstance(op, str) else '',
    )
