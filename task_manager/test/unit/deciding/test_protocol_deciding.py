"""The JSON protocol of what decides what runs (issue 29): a start's options, a task's place in
the queue, priority, attempt and decisions, an event's reason, reprioritize and why."""

import json
from datetime import UTC, datetime
from typing import Any

import jsonschema
import pytest
from pydantic import ValidationError

from task_manager.client import Decision, TaskEvent, TaskEventKind, TaskState
from task_manager.core.status import TaskStatus
from task_manager.gateway.documents import event_json, task_json
from task_manager.gateway.requests import options_of
from task_manager.protocol import models, mqtt
from task_manager.protocol.__main__ import SCHEMA_FOLDER

QUEUED_AT = datetime(2026, 11, 23, 2, 0, tzinfo=UTC)
REASON = 'queued behind drive-1 (priority 5), which holds base'


def validator(name: str) -> jsonschema.Draft202012Validator:
    schema = json.loads((SCHEMA_FOLDER / f'{name}.schema.json').read_text())
    return jsonschema.Draft202012Validator(schema, format_checker=jsonschema.FormatChecker())


def test_a_queued_task_document_has_its_place_priority_attempt_and_decisions() -> None:
    state = TaskState(
        'dock-1', 'dock', TaskStatus.QUEUED, 'WEB', received_at=QUEUED_AT, queue_position=2,
        priority=3, decisions=[Decision(QUEUED_AT, 'queued', REASON)],
    )  # fmt: skip

    document = task_json(state)
    event = event_json(TaskEvent(TaskEventKind.QUEUED, QUEUED_AT, state, REASON))

    validator('task').validate(document)
    validator('task_event').validate(event)
    assert (document['queue_position'], document['priority'], document['attempt']) == (2, 3, 1)
    assert document['decisions'] == [
        {'at': '2026-11-23T02:00:00Z', 'decision': 'queued', 'reason': REASON, 'omitted': 0}
    ]
    assert (event['event'], event['reason']) == ('QUEUED', REASON)


def test_the_options_of_a_start_are_the_client_keywords_given() -> None:
    body = {
        'task_name': 'dock',
        'priority': -3,
        'on_conflict': 'queue',
        'timeout_sec': 2,
        'queue_timeout_sec': 0.5,
    }

    validator('start_task').validate(body)
    options = options_of(models.StartTask.model_validate(body))
    mission = models.StartMission.model_validate({'subtasks': [{'task_name': 'a'}], 'priority': 0})

    assert options == {
        'priority': -3,
        'on_conflict': 'queue',
        'timeout_sec': 2.0,
        'queue_timeout_sec': 0.5,
    }
    assert options_of(mission) == {'priority': 0}
    assert options_of(models.StartTask.model_validate({'task_name': 'a'})) == {}


@pytest.mark.parametrize(
    ('body', 'field'),
    [
        ({'priority': True}, 'priority'),
        ({'priority': '5'}, 'priority'),
        ({'priority': 2**31}, 'priority'),
        ({'on_conflict': 'wait'}, 'on_conflict'),
        ({'timeout_sec': 0}, 'timeout_sec'),
        ({'queue_timeout_sec': -1.0}, 'queue_timeout_sec'),
        ({'feedback_timeout_sec': '1'}, 'feedback_timeout_sec'),
    ],
)
def test_an_unusable_option_is_refused_naming_it(body: dict[str, Any], field: str) -> None:
    request = {'task_name': 'dock', **body}

    with pytest.raises(ValidationError) as refused:
        models.StartTask.model_validate(request)

    assert refused.value.errors()[0]['loc'][0] == field
    assert not validator('start_task').is_valid(request)


def test_reprioritize_and_why_are_requests_of_the_mqtt_protocol() -> None:
    reprioritize = {'op': 'reprioritize', 'request_id': 'r1', 'task_ids': ['a'], 'priority': 4}
    why = {'op': 'why', 'request_id': 'r2', 'task_id': 'a'}
    decision = {'at': '2026-11-23T02:00:00Z', 'decision': 'queued', 'reason': REASON}
    reply = {'request_id': 'r2', 'ok': True, 'op': 'why', 'decisions': [decision]}

    for document in (reprioritize, why):
        validator('mqtt_request').validate(document)
    validator('mqtt_reply').validate(reply)
    assert isinstance(mqtt.RobotRequest.model_validate(why).root, mqtt.WhyRequest)
    raised = mqtt.RobotRequest.model_validate(reprioritize).root
    assert isinstance(raised, mqtt.ReprioritizeRequest) and raised.priority == 4
    validator('reprioritize').validate({'task_ids': ['a'], 'priority': -1})
    for bad in ({'task_ids': [], 'priority': 1}, {'task_ids': ['a']}):
        assert not validator('reprioritize').is_valid(bad)
    assert not validator('mqtt_request').is_valid({**why, 'task_id': ''})
    validator('decision').validate(decision)
    assert models.Decision.model_validate(decision).at == QUEUED_AT
