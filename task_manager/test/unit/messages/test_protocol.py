"""The JSON protocol of the gateways: its schema files, and the client's records as its JSON."""

import json
from datetime import UTC, datetime, timedelta
from typing import get_args

import jsonschema
import pytest
from pydantic import BaseModel, ValidationError

from task_manager.client import TaskEvent, TaskEventKind, TaskResult, TaskState
from task_manager.core.status import ErrorCode, TaskStatus
from task_manager.core.task_spec import PauseMode
from task_manager.gateway.documents import declared_json, event_json, result_json, task_json
from task_manager.protocol import models, mqtt
from task_manager.protocol.__main__ import SCHEMA_FOLDER, schema_documents

STARTED = datetime(2026, 11, 23, 2, 0, tzinfo=UTC)


def validator(name: str) -> jsonschema.Draft202012Validator:
    schema = json.loads((SCHEMA_FOLDER / f'{name}.schema.json').read_text())
    return jsonschema.Draft202012Validator(schema, format_checker=jsonschema.FormatChecker())


def test_the_schema_files_are_those_of_the_models() -> None:
    written = {path.name: path.read_text() for path in SCHEMA_FOLDER.glob('*.schema.json')}

    assert written == schema_documents(), 'run `python -m task_manager.protocol` to update them'
    for text in written.values():
        jsonschema.Draft202012Validator.check_schema(json.loads(text))


def test_statuses_and_error_codes_are_those_of_the_interfaces() -> None:
    assert set(get_args(models.TaskStatusName)) == {s.value for s in TaskStatus}
    assert set(get_args(models.ErrorCodeName)) == {c.value for c in ErrorCode}
    assert set(get_args(models.EventName)) == {k.value for k in TaskEventKind}
    assert set(get_args(models.PauseModeName)) == {m.value for m in PauseMode}


@pytest.mark.parametrize(
    ('declared', 'shown'), [(None, 'none'), ('restart', 'restart'), (' Restart', 'restart')]
)
def test_a_declared_task_says_how_it_pauses(declared: str | None, shown: str) -> None:
    entry = {'key': 'nav', 'task_name': 'nav', 'msg_interface': 'test_msgs/action/Fibonacci'}
    if declared is not None:
        entry['pause'] = declared

    document = declared_json(entry)

    validator('declared_task').validate(document)
    assert document['pause'] == shown


def test_an_ended_task_is_a_valid_task_document() -> None:
    state = TaskState(
        'id-1', 'navigate', TaskStatus.DONE, 'WEB', mission_id='m-1',
        received_at=STARTED - timedelta(seconds=1), started_at=STARTED,
        ended_at=STARTED + timedelta(seconds=2.5), feedback={'left': 0.0},
        result={'x': 1.0}, sequence=7,
    )  # fmt: skip

    document = task_json(state)

    validator('task').validate(document)
    assert document['started'] == '2026-11-23T02:00:00Z'
    assert (document['duration_sec'], document['sequence']) == (2.5, 7)
    assert (document['result'], document['feedback']) == ({'x': 1.0}, {'left': 0.0})


def test_a_running_task_has_no_result_nor_duration_yet() -> None:
    state = TaskState('id-2', 'spin', TaskStatus.IN_PROGRESS, 'CLOUD', started_at=STARTED)

    document = task_json(state)

    validator('task').validate(document)
    assert (document['ended'], document['duration_sec'], document['result']) == (None, None, None)


def test_a_refusal_carries_its_error_message() -> None:
    result = TaskResult(
        'id-3', 'nope', TaskStatus.ERROR, ErrorCode.UNKNOWN_TASK, {'error': 'unknown task nope'}
    )

    document = result_json(result)

    validator('task').validate(document)
    assert (document['error_code'], document['error_message']) == (
        'unknown_task',
        'unknown task nope',
    )


def test_an_event_is_a_valid_task_event_document() -> None:
    state = TaskState('id-4', 'spin', TaskStatus.RECEIVED, 'WEB', received_at=STARTED)
    event = TaskEvent(TaskEventKind.RECEIVED, STARTED, state)

    validator('task_event').validate(event_json(event))


@pytest.mark.parametrize(
    ('body', 'field'),
    [
        ({}, 'task_name'),
        ({'task_name': ''}, 'task_name'),
        ({'task_name': 'a', 'task_data': 'text'}, 'task_data'),
        ({'task_name': 'a', 'surprise': 1}, 'surprise'),
        ({'task_name': 'a' * 257}, 'task_name'),
        ({'task_name': 'a', 'source': 'CLOUD'}, 'source'),  # the web gateway sets it
    ],
)
def test_a_bad_start_request_names_its_field(body: dict[str, object], field: str) -> None:
    with pytest.raises(ValidationError) as raised:
        models.StartTask.model_validate(body)

    assert raised.value.errors()[0]['loc'][0] == field
    assert not validator('start_task').is_valid(body)


def test_the_schema_and_the_model_agree_on_a_good_mission() -> None:
    body = {'subtasks': [{'task_name': 'a', 'task_data': {'x': 1}, 'allow_skipping': True}]}

    validator('start_mission').validate(body)
    assert models.StartMission.model_validate(body).subtasks[0].allow_skipping


@pytest.mark.parametrize(
    ('model', 'body', 'field'),
    [
        (models.StartTask, {'task_name': 'camera/take_photo\x00junk'}, 'task_name'),
        (models.StartTask, {'task_name': 'fib', 'task_id': 'a\nb'}, 'task_id'),
        (
            mqtt.StartTaskRequest,
            {'op': 'start_task', 'request_id': 'r', 'task_name': 'fib', 'source': '\u202eDUOLC'},
            'source',
        ),
        (models.StartMission, {'subtasks': [{'task_name': 'x\x1b'}]}, 'subtasks.0.task_name'),
        (models.CancelTasks, {'task_ids': ['ok', 'no\x00']}, 'task_ids.1'),
    ],
)
def test_control_and_reordering_characters_are_refused_at_the_door(
    model: type[BaseModel], body: dict[str, object], field: str
) -> None:
    with pytest.raises(ValidationError) as refused:
        model.model_validate(body)

    (error,) = refused.value.errors()
    assert '.'.join(str(part) for part in error['loc']) == field
    assert 'control characters' in error['msg']
