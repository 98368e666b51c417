"""Pauses in the Python client: TaskState's paused time and pauses, running time, and the
system/pause and system/resume requests it sends."""

import json
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
from builtin_interfaces.msg import Time
from task_manager_msgs.msg import TaskEvent as TaskEventMessage
from task_manager_msgs.msg import TaskState as TaskStateMessage

from task_manager.client import Pause, TaskEvent, TaskEventKind, TaskResult, TaskState
from task_manager.client.interventions import Interventions
from task_manager.client.records import parse_pauses
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.gateway.documents import result_json, task_json

EPOCH = 1_800_000_000  # 2027-01-15T08:00:00Z
T0 = datetime.fromtimestamp(EPOCH, UTC)


def _at(seconds: float) -> datetime:
    return T0 + timedelta(seconds=seconds)


def _pauses(*spans: tuple[float, float | None]) -> str:
    return json.dumps(
        [
            {
                'paused': EPOCH + paused,
                'paused_by': 'operator',
                'resumed': None if resumed is None else EPOCH + resumed,
                'resumed_by': None if resumed is None else 'UI',
            }
            for paused, resumed in spans
        ]
    )


def _state(status: str, pauses: str, paused_sec: float, ended: Time | None = None) -> TaskState:
    return TaskState.from_message(
        TaskStateMessage(
            task_id='t1',
            task_name='nav',
            task_status=status,
            started=Time(sec=EPOCH),
            ended=ended or Time(),
            paused_sec=paused_sec,
            pauses=pauses,
        )
    )


def test_paused_sec_and_pauses_are_parsed() -> None:
    state = _state('IN_PROGRESS', _pauses((2, 5.5)), 3.5)

    assert state.paused == timedelta(seconds=3.5)
    assert state.pauses == [Pause(_at(2), 'operator', _at(5.5), 'UI')]


def test_a_task_never_paused_has_no_pauses() -> None:
    state = TaskState.from_message(TaskStateMessage(task_id='t', task_status='RECEIVED'))

    assert (state.paused, state.pauses) == (timedelta(0), [])
    assert parse_pauses('[]') == []


@pytest.mark.parametrize(
    'text', ['', 'not json', '{}', '[1, "x", {"paused": "soon"}, {"paused": true}]']
)
def test_pauses_that_cannot_be_read_are_left_out(text: str) -> None:
    assert parse_pauses(text) == []


def test_an_open_pause_has_no_resume_yet() -> None:
    (pause,) = parse_pauses(_pauses((4, None)))

    assert (pause.resumed_at, pause.resumed_by) == (None, '')
    assert pause.length(_at(10)) == timedelta(seconds=6)


def test_running_time_does_not_count_a_finished_pause() -> None:
    state = _state('IN_PROGRESS', _pauses((2, 5)), 3)

    assert state.elapsed(_at(10)) == timedelta(seconds=7)


def test_the_clock_stops_while_paused() -> None:
    state = _state('PAUSED', _pauses((1, 2), (6, None)), 1)

    assert state.elapsed(_at(8)) == timedelta(seconds=5)
    assert state.elapsed(_at(60)) == timedelta(seconds=5)


def test_without_pauses_paused_sec_is_the_time_paused() -> None:
    state = _state('IN_PROGRESS', '', 4)

    assert state.elapsed(_at(10)) == timedelta(seconds=6)


def test_an_ended_task_ran_from_start_to_end_less_its_pauses() -> None:
    state = _state('DONE', _pauses((1, 3)), 2, ended=Time(sec=EPOCH + 10))

    result = state.to_result()

    assert state.elapsed() == result.duration == timedelta(seconds=8)
    assert result.paused == timedelta(seconds=2)


def test_a_task_that_ended_paused_ran_until_its_pause() -> None:
    state = _state('CANCELED', _pauses((4, None)), 0, ended=Time(sec=EPOCH + 30))

    assert state.to_result().duration == state.elapsed() == timedelta(seconds=4)


def test_a_result_with_the_stamps_of_its_state_has_its_paused_time() -> None:
    state = _state('DONE', _pauses((1, 3)), 2, ended=Time(sec=EPOCH + 10))
    bare = TaskResult('t1', 'nav', TaskStatus.DONE, ErrorCode.NONE, {})

    assert bare.with_stamps_of(state).duration == timedelta(seconds=8)


def test_pause_and_resume_are_events() -> None:
    for kind in (TaskEventKind.PAUSED, TaskEventKind.RESUMED):
        message = TaskEventMessage(
            event=kind.value,
            stamp=Time(sec=EPOCH),
            task=TaskStateMessage(task_id='t', task_status='PAUSED', pauses=_pauses((0, None))),
        )

        event = TaskEvent.from_message(message)

        assert (event.kind, event.task.status) == (kind, TaskStatus.PAUSED)
        assert event.task.pauses[0].paused_at == T0


def test_task_documents_carry_the_running_time_and_the_time_paused() -> None:
    state = _state('DONE', _pauses((1, 3)), 2, ended=Time(sec=EPOCH + 10))

    document = task_json(state)

    assert (document['duration_sec'], document['paused_sec']) == (8.0, 2.0)
    assert result_json(state.to_result())['paused_sec'] == 2.0


class RecordingClient(Interventions):
    """The client's interventions, recording the system tasks they would run instead."""

    def __init__(self) -> None:
        self.started: list[tuple[str, Any, dict[str, Any]]] = []

    def _system_task(
        self, task_name: str, data: dict[str, Any], *, source: str, timeout_sec: float | None
    ) -> TaskResult:
        self.started.append((task_name, data, {'timeout_sec': timeout_sec, 'source': source}))
        return TaskResult('id', task_name, TaskStatus.DONE, ErrorCode.NONE, {})


def test_pause_and_resume_run_their_system_tasks() -> None:
    client = RecordingClient()

    client.pause(('a', 'b'), source='operator')
    client.resume(['a'], timeout_sec=3.0)

    assert client.started == [
        ('system/pause', {'task_ids': ['a', 'b']}, {'timeout_sec': None, 'source': 'operator'}),
        ('system/resume', {'task_ids': ['a']}, {'timeout_sec': 3.0, 'source': 'python'}),
    ]
