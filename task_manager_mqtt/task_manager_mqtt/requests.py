"""The bridge's answers to the cloud's requests: one reply or one dead letter per message.

A message is read by `decoding.decode` (which bounds its size and depth before parsing);
a bad one with a usable request_id gets an error reply naming what is wrong and what is
allowed (`invalid_request`, `payload_too_large`, `nesting_too_deep`, `retained_request`),
one without is a dead letter (see Answer). No Task Manager is `task_manager_unavailable`.
A start whose task id the Task Manager already knows starts nothing: the reply is that
task, with `duplicate: true`; `why` of a task it does not know is `unknown_task_id`, and
`unschedule` or `enable_schedules` of a schedule it does not have `unknown_schedule_id`, and
`confirm` of a task that is no waiting confirmation `not_waiting`. What a start starts, and
the answer of a confirm, have the bridge's source followed by the name the request's `source`
gives (`CLOUD:alice`); one that claims another door's source (`WEB:boss`) is
`invalid_request`. Pause, resume, the schedules and confirm go through the same calls as the
web gateway's routes (`task_manager.gateway.requests`). Whatever happens, `answer` returns
one Answer.
"""

import contextlib
import logging
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

from task_manager.client import TaskHandle, TaskManagerClient, TaskState
from task_manager.core.confirmation import AnswerRefusal
from task_manager.core.errors import TaskManagerUnavailable
from task_manager.core.status import TaskStatus
from task_manager.gateway import requests as gateway_requests
from task_manager.gateway.documents import (
    confirmed_json,
    decisions_json,
    paused_json,
    result_json,
    resumed_json,
    schedule_json,
    scheduled_json,
    task_json,
)
from task_manager.protocol import mqtt
from task_manager.protocol.errors import RefusalCode
from task_manager_mqtt.decoding import Decoded, decode, refusal

LOG = logging.getLogger('task_manager_mqtt')
NODE_WAIT_SEC = 5.0


REMEMBERED_STARTS = 1000
"""Tasks the bridge started whose id it remembers, for requests delivered again."""
OperatorRequest = (
    mqtt.PauseRequest
    | mqtt.ResumeRequest
    | mqtt.ScheduleRequest
    | mqtt.UnscheduleRequest
    | mqtt.EnableSchedulesRequest
    | mqtt.SchedulesRequest
    | mqtt.ConfirmRequest
)


class Refusal(Exception):  # noqa: N818 - an answer, not a failure of the bridge
    """A request the bridge answers with an error reply (an ErrorDetail document)."""

    def __init__(self, code: str, message: str, field: str = '') -> None:
        super().__init__(message)
        self.detail = refusal(code, message, field)


@dataclass(frozen=True)
class Answer:
    """The one outcome of a request message: a Reply document, or the reason (an ErrorDetail
    document) it is a dead letter, having no request_id to address a reply to."""

    reply: dict[str, Any] | None = None
    dead_letter: dict[str, str] | None = None


class RequestHandler:
    """Runs each request through the Task Manager client (blocking: call it from a worker)."""

    def __init__(self, client: TaskManagerClient, source: str, max_payload_bytes: int) -> None:
        self.client = client
        self.source = source
        self.max_payload_bytes = max_payload_bytes
        self._waited_for_node = False
        # key: task id, value: the handle of a task this bridge started (the latest ones): a
        # request delivered again may come before the node has admitted the first one
        self._started: OrderedDict[str, TaskHandle] = OrderedDict()

    def answer(self, payload: bytes, retained: bool = False) -> Answer:
        """The reply to the request message `payload`, or why it is a dead letter."""
        decoded = decode(payload, self.max_payload_bytes, retained)
        if decoded.error is not None and not decoded.addressed:
            return Answer(dead_letter=decoded.error)
        try:
            document = self._reply(decoded)
            return Answer(reply=mqtt.Reply.model_validate(document).model_dump(mode='json'))
        except Exception as error:  # the reply could not be made: an error reply instead
            LOG.error('the reply to %r failed: %s: %s', decoded.request_id, type(error).__name__,
                      error)  # fmt: skip
            message = f'the bridge failed: {type(error).__name__}'
            detail = refusal(RefusalCode.INTERNAL_ERROR, message)
            return Answer(reply=_error_reply(decoded, detail))

    def _reply(self, decoded: Decoded) -> dict[str, Any]:
        request_id, op = decoded.request_id, decoded.op
        if decoded.error is not None:
            LOG.warning('request %r (%s) refused: %s', request_id, op or '?',
                        decoded.error['message'][:200])  # fmt: skip
            return _error_reply(decoded, decoded.error)
        try:
            return {'request_id': request_id, 'ok': True, 'op': op, **self._run(decoded.request)}
        except TaskManagerUnavailable as error:
            return _error_reply(decoded, refusal(RefusalCode.TASK_MANAGER_UNAVAILABLE, str(error)))
        except Refusal as refused:
            return _error_reply(decoded, refused.detail)
        except Exception as error:  # one line, a reply; the bridge goes on
            LOG.error('request %r (%s) failed: %s: %s', request_id, op, type(error).__name__, error)
            message = f'the bridge failed: {type(error).__name__}'
            return _error_reply(decoded, refusal(RefusalCode.INTERNAL_ERROR, message))

    def _run(self, request: Any) -> dict[str, Any]:
        self._wait_for_node_once()
        if not self.client.connected:
            raise TaskManagerUnavailable(
                "the Task Manager is not reachable from the robot's bridge"
            )
        if isinstance(request, OperatorRequest):
            return self._operate(request)
        match request:
            case mqtt.StartTaskRequest():
                return self._start_task(request)
            case mqtt.StartMissionRequest():
                return self._start_mission(request)
            case mqtt.CancelRequest():
                result = gateway_requests.cancel_tasks(self.client, request, source=self.source)
                return {'task': result_json(result)}
            case mqtt.StopRequest():
                return {'task': result_json(self.client.stop(source=self.source))}
            case mqtt.HistoryRequest():
                filters = request.model_dump(exclude={'request_id', 'op'})
                return {'tasks': [task_json(s) for s in self.client.history(**filters)]}
            case mqtt.ReprioritizeRequest():
                self.client.wait_until_available()
                result = gateway_requests.reprioritize(self.client, request, source=self.source)
                return {'task': result_json(result)}
            case mqtt.WhyRequest():
                decisions = gateway_requests.why(self.client, request.task_id)
                if decisions is None:
                    message = f'the Task Manager knows no task {request.task_id!r}'
                    raise Refusal(RefusalCode.UNKNOWN_TASK_ID, message, 'task_id')
                return {'decisions': decisions_json(decisions)}
        raise AssertionError(f'unhandled request {request!r}')

    def _operate(self, request: OperatorRequest) -> dict[str, Any]:
        """pause, resume and the schedules' ops: the system task, ended, and the answer;
        confirm: the answer."""
        client, source = self.client, self.source
        if isinstance(request, mqtt.SchedulesRequest):
            return {'schedules': [schedule_json(s) for s in client.schedules(request.schedule_ids)]}
        if isinstance(request, mqtt.ConfirmRequest):
            return self._confirm(request)
        client.wait_until_available()
        match request:
            case mqtt.PauseRequest():
                result = gateway_requests.pause(client, request, source=source)
                return {'task': result_json(result), 'paused': paused_json(result)}
            case mqtt.ResumeRequest():
                result = gateway_requests.resume(client, request, source=source)
                return {'task': result_json(result), 'resumed': resumed_json(result)}
            case mqtt.ScheduleRequest():
                result = gateway_requests.schedule(client, request, source=source)
                scheduled = scheduled_json(result, request.schedule_id)
                return {'task': result_json(result), 'scheduled': scheduled}
            case mqtt.UnscheduleRequest():
                removed = gateway_requests.unschedule(client, request.schedule_id, source=source)
                if removed is None:
                    raise _unknown_schedule(request.schedule_id, 'schedule_id')
                return {'task': result_json(removed)}
            case mqtt.EnableSchedulesRequest():
                return self._enable_schedules(request)
        raise AssertionError(f'unhandled request {request!r}')

    def _confirm(self, request: mqtt.ConfirmRequest) -> dict[str, Any]:
        source = self._source_of(request)
        answer = gateway_requests.confirm(self.client, request.task_id, request, source=source)
        if answer.taken:
            return {'confirmed': confirmed_json(answer, request, source)}
        if answer.error_code == AnswerRefusal.NOT_FOUND:
            raise Refusal(RefusalCode.UNKNOWN_TASK_ID, answer.message, 'task_id')
        if answer.error_code == AnswerRefusal.NOT_WAITING:
            raise Refusal(RefusalCode.NOT_WAITING, answer.message, 'task_id')
        raise Refusal(answer.error_code or RefusalCode.INVALID_REQUEST, answer.message)

    def _enable_schedules(self, request: mqtt.EnableSchedulesRequest) -> dict[str, Any]:
        try:
            result, changed = gateway_requests.enable_schedules(
                self.client, request.schedule_ids, request, source=self.source
            )
        except gateway_requests.UnknownScheduleError as unknown:
            raise _unknown_schedule(unknown.schedule_id, f'schedule_ids.{unknown.index}') from None
        return {'task': result_json(result), 'schedules': [schedule_json(s) for s in changed]}

    def _wait_for_node_once(self) -> None:
        """Before the first request to run: those the broker kept while the bridge was away
        come as it connects, usually before it has found its Task Manager; they wait for it
        (at most NODE_WAIT_SEC, once) rather than being refused `task_manager_unavailable`."""
        if self._waited_for_node:
            return
        self._waited_for_node = True
        if not self.client.connected:
            with contextlib.suppress(TaskManagerUnavailable):
                self.client.wait_until_available(NODE_WAIT_SEC)

    def _start_task(self, request: mqtt.StartTaskRequest) -> dict[str, Any]:
        source = self._source_of(request)
        task_id = request.task_id or request.request_id
        if (known := self._known(task_id)) is not None:
            return known
        self.client.wait_until_available()
        handle = gateway_requests.start_task(self.client, request, task_id=task_id, source=source)
        self._remember(handle)
        return _started(handle)

    def _start_mission(self, request: mqtt.StartMissionRequest) -> dict[str, Any]:
        source = self._source_of(request)
        task_id = request.task_id or request.request_id
        if (known := self._known(task_id)) is not None:
            return known
        self.client.wait_until_available()
        handle, subtask_ids = gateway_requests.start_mission(
            self.client, request, task_id=task_id, source=source
        )
        self._remember(handle)
        return {**_started(handle), 'subtask_ids': subtask_ids}

    def _source_of(
        self, request: mqtt.StartTaskRequest | mqtt.StartMissionRequest | mqtt.ConfirmRequest
    ) -> str:
        """The bridge's source (`CLOUD`), followed by the name the request gives, if any
        (`CLOUD:alice`): never another door's."""
        try:
            return gateway_requests.claimed_source(self.source, request.source)
        except ValueError as error:
            raise Refusal(RefusalCode.INVALID_REQUEST, str(error), 'source') from None

    def _known(self, task_id: str) -> dict[str, Any] | None:
        """The reply to a start of a task id the Task Manager knows (active or ended)."""
        states = self.client.task_states([task_id])
        handle = self._started.get(task_id)
        if not states and handle is None:
            return None
        LOG.info('task %r is known already (a request delivered again?): nothing started', task_id)
        state = states[0] if states else handle_state(handle)
        return {'task_id': task_id, 'duplicate': True, 'task': task_json(state)}

    def _remember(self, handle: TaskHandle) -> None:
        self._started[handle.task_id] = handle
        self._started.move_to_end(handle.task_id)
        while len(self._started) > REMEMBERED_STARTS:
            self._started.popitem(last=False)


def handle_state(handle: Any) -> TaskState:
    """What the bridge knows of a task it started: its latest event, else RECEIVED."""
    state: TaskState | None = handle.state
    if state is not None:
        return state
    return TaskState(handle.task_id, handle.task_name, TaskStatus.RECEIVED, handle.source)


def _started(handle: TaskHandle) -> dict[str, Any]:
    state: TaskState | None = handle.state
    return {'task_id': handle.task_id, 'task': None if state is None else task_json(state)}


def _unknown_schedule(schedule_id: str, field: str) -> Refusal:
    message = f'the Task Manager has no schedule {schedule_id!r}'
    return Refusal(RefusalCode.UNKNOWN_SCHEDULE_ID, message, field)


def _error_reply(decoded: Decoded, detail: dict[str, str]) -> dict[str, Any]:
    return {'request_id': decoded.request_id, 'ok': False, 'op': decoded.op, 'error': detail}
