"""Pause, resume, schedules and confirmations through the bridge (issue 30): the FleetClient's
calls over a real mosquitto to a real Task Manager, and the error replies to bad requests."""

import json
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest

from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check, wait_until
from task_manager_mqtt.fleet_client import FleetClient
from task_manager_mqtt.fleet_types import FleetError
from task_manager_mqtt.settings import DEFAULT_PREFIX
from task_manager_mqtt.testing import ROBOT, TESTER, BrokerProcess, RawClient
from task_manager_mqtt.topics import Topics

pytestmark = pytest.mark.ros
INSTANT = {'task_name': 'instant', 'task_data': {'data': True}}
# each: a bad request, the code and field of its error reply, words of its message
BAD_REQUESTS: list[tuple[dict[str, Any], str, str, str]] = [
    ({'op': 'schedule', 'task_name': 'instant', 'delay_sec': 5.0, 'period_sec': 60.0},
     'invalid_request', '', 'exactly one of at, delay_sec, period_sec, cron; got delay_sec and '
     'period_sec'),
    ({'op': 'schedule', 'delay_sec': 5.0}, 'invalid_request', '', 'give either task_name'),
    ({'op': 'schedule', 'task_name': 'instant', 'period_sec': 60.0, 'every': 5},
     'invalid_request', 'every', 'unknown field'),
    ({'op': 'unschedule'}, 'invalid_request', 'schedule_id', 'Field required'),
    ({'op': 'enable_schedules', 'schedule_ids': ['kept']}, 'invalid_request', 'enabled',
     'Field required'),
    ({'op': 'pause', 'task_ids': []}, 'invalid_request', 'task_ids', 'at least 1'),
    ({'op': 'unschedule', 'schedule_id': 'nope'}, 'unknown_schedule_id', 'schedule_id',
     "no schedule 'nope'"),
    ({'op': 'enable_schedules', 'schedule_ids': ['kept', 'nope'], 'enabled': False},
     'unknown_schedule_id', 'schedule_ids.1', "no schedule 'nope'"),
]  # fmt: skip


def test_a_mission_paused_and_resumed_from_the_cloud(robot: Robot, online: FleetClient) -> None:
    events: list[dict[str, Any]] = []
    online.on_event(lambda _, event: events.append(check(event, 'task_event')))
    fib = {'task_name': 'fib', 'task_data': {'order': 1}}
    mission = online.start_mission(ROBOT, [fib, fib])
    check(mission.accepted(), 'mqtt_reply')
    first = robot.fib.wait_for_goals(1, TIMEOUT_SEC)[0]

    paused = check(online.pause(ROBOT, [mission.task_id, 'ghost']), 'paused')

    assert paused['paused'] == [mission.task_id]
    assert len(paused['errors']) == 1 and "'ghost'" in paused['errors'][0]
    system_task = (paused['task']['task_name'], paused['task']['status'], paused['task']['source'])
    assert system_task == ('system/pause', 'ERROR', 'CLOUD')
    wait_until(lambda: changes_of(events, mission.task_id)[-1:] == [('PAUSED', 'PAUSED')],
               'the PAUSED event')  # fmt: skip

    resumed = check(online.resume(ROBOT, [mission.task_id]), 'resumed')

    assert (resumed['resumed'], resumed['errors']) == ([mission.task_id], [])
    assert (resumed['task']['task_name'], resumed['task']['status']) == ('system/resume', 'DONE')
    wait_until(lambda: changes_of(events, mission.task_id)[-1:] == [('RESUMED', 'IN_PROGRESS')],
               'the RESUMED event')  # fmt: skip
    again = check(online.resume(ROBOT, [mission.task_id]), 'resumed')
    assert again['resumed'] == [] and len(again['errors']) == 1
    first.succeed()
    robot.fib.wait_for_goals(2, TIMEOUT_SEC)[1].succeed()
    ended = check(mission.result(), 'task')
    assert ended['status'] == 'DONE' and ended['paused_sec'] > 0


def test_a_task_scheduled_with_a_delay_runs_and_ends_done(online: FleetClient) -> None:
    results: list[dict[str, Any]] = []
    online.on_result(lambda _, task: results.append(task))

    scheduled = check(
        online.schedule_task(
            ROBOT, 'instant', {'data': True}, schedule_id='soon', delay_sec=0.5, priority=2
        ),
        'scheduled',
    )

    assert (scheduled['scheduled'], scheduled['schedule_id']) == (True, 'soon')
    assert scheduled['next_run'] and scheduled['message']
    system_task = scheduled['task']
    assert (system_task['task_name'], system_task['status'], system_task['source']) == (
        'system/schedule',
        'DONE',
        'CLOUD',
    )
    runs = wait_until(lambda: [t for t in results if t['source'] == 'schedule:soon'], 'the run')
    assert [(t['task_name'], t['status'], t['priority']) for t in runs] == [('instant', 'DONE', 2)]
    listed = wait_until(
        lambda: [s for s in online.schedules(ROBOT, ['soon']) if s['last_status'] == 'DONE'],
        'the run in the schedule',
    )
    schedule = check(listed[0], 'schedule')
    assert (schedule['run_count'], schedule['last_task_id'], schedule['created_by']) == (
        1,
        runs[0]['task_id'],
        'CLOUD',
    )
    assert schedule['options'] == {'priority': 2} and schedule['next_run'] is None


def test_schedules_are_listed_disabled_enabled_and_removed(online: FleetClient) -> None:
    nightly = online.schedule_task(
        ROBOT,
        'fib',
        {'order': 3},
        schedule_id='nightly',
        cron='0 2 * * *',
        time_zone='Europe/Paris',
        timeout_sec=60.0,
    )
    later = online.schedule_mission(
        ROBOT, [INSTANT], schedule_id='later', at=datetime.now(UTC) + timedelta(hours=1)
    )
    refused = online.schedule_task(ROBOT, 'no/such_task', period_sec=60.0)
    assert nightly['scheduled'] and later['scheduled']
    assert refused['scheduled'] is False and 'no/such_task' in refused['message']
    assert refused['task']['status'] == 'ERROR'

    reply = check(online.request(ROBOT, 'schedules').result(TIMEOUT_SEC), 'mqtt_reply')

    by_id = {s['schedule_id']: s for s in reply['schedules']}
    assert set(by_id) == {'nightly', 'later'}
    cron, mission = by_id['nightly'], by_id['later']
    assert (cron['cron'], cron['time_zone'], cron['options']) == (
        '0 2 * * *',
        'Europe/Paris',
        {'timeout_sec': 60},
    )
    assert (mission['task_name'], mission['created_by']) == ('system/mission', 'CLOUD')
    assert [s['schedule_id'] for s in online.schedules(ROBOT, ['later', 'gone'])] == ['later']

    disabled = online.enable_schedules(ROBOT, ['nightly', 'later'], False)

    assert [(s['schedule_id'], s['enabled'], s['next_run']) for s in disabled] == [
        ('nightly', False, None),
        ('later', False, None),
    ]
    (enabled,) = online.enable_schedules(ROBOT, ['nightly'], True)
    assert enabled['enabled'] and enabled['next_run']

    removed = check(online.unschedule(ROBOT, 'nightly'), 'task')

    assert (removed['task_name'], removed['status'], removed['source']) == (
        'system/unschedule',
        'DONE',
        'CLOUD',
    )
    assert [(s['schedule_id'], s['enabled']) for s in online.schedules(ROBOT)] == [('later', False)]


def test_each_bad_request_gets_one_error_reply_naming_the_field_and_nothing_is_done(
    online: FleetClient, broker: BrokerProcess
) -> None:
    kept = online.schedule_task(ROBOT, 'fib', {'order': 1}, schedule_id='kept', period_sec=3600.0)
    assert kept['scheduled'], kept
    topics = Topics(DEFAULT_PREFIX, ROBOT)
    with RawClient(broker.port, TESTER, broker.passwords[TESTER], topics=[topics.reply]) as raw:
        sent = [
            online.request(ROBOT, request['op'], request_id=f'bad-{n}', **without_op(request))
            for n, (request, *_) in enumerate(BAD_REQUESTS)
        ]

        replies = [check(reply.result(TIMEOUT_SEC), 'mqtt_reply') for reply in sent]

        check(online.pause(ROBOT, ['ghost']), 'paused')  # a system task after them all
        raw.wait_for(lambda got: len(replied(got, 'bad-')) >= len(BAD_REQUESTS), 'the replies')
        received = replied(raw.received, 'bad-')
    for reply, (_, code, field, words) in zip(replies, BAD_REQUESTS, strict=True):
        assert reply['ok'] is False, reply
        assert (reply['error']['code'], reply['error']['field']) == (code, field), reply
        assert words in reply['error']['message'], reply
    assert sorted(received) == sorted(f'bad-{n}' for n in range(len(BAD_REQUESTS)))
    (kept,) = online.schedules(ROBOT)
    assert (kept['schedule_id'], kept['enabled']) == ('kept', True)

    def ran() -> list[str]:
        return [t['task_name'] for t in online.history(ROBOT, source='CLOUD', oldest_first=True)]

    names = wait_until(lambda: (n := ran())[-1:] == ['system/pause'] and n, 'the pause stored')
    assert names == ['system/schedule', 'system/pause']
    with pytest.raises(FleetError) as unknown:
        online.unschedule(ROBOT, 'nope')
    assert unknown.value.code == 'unknown_schedule_id'


def test_a_mission_waits_at_its_confirmation_until_the_cloud_confirms_it(
    online: FleetClient,
) -> None:
    events: list[dict[str, Any]] = []
    online.on_event(lambda _, event: events.append(check(event, 'task_event')))
    step = {'task_name': 'system/confirm', 'task_data': {'prompt': 'Load the tray'}}
    mission = online.start_mission(ROBOT, [step, INSTANT])
    confirm_id, instant_id = check(mission.accepted(), 'mqtt_reply')['subtask_ids']
    waiting = wait_until(
        lambda: [e for e in events if e['task']['task_id'] == confirm_id and e['task']['feedback']],
        'the prompt as feedback',
    )
    assert waiting[0]['task']['feedback']['prompt'] == 'Load the tray'
    assert not [e for e in events if e['task']['task_id'] == instant_id]  # the mission waits

    confirmed = check(online.confirm(ROBOT, confirm_id, comment='tray loaded'), 'confirmed')

    assert confirmed == {
        'task_id': confirm_id,
        'outcome': 'confirmed',
        'by': 'CLOUD',
        'comment': 'tray loaded',
    }
    assert check(mission.result(), 'task')['status'] == 'DONE'
    (stored,) = online.history(ROBOT, task_name='system/confirm')
    assert (stored['status'], stored['result']['by'], stored['result']['outcome']) == (
        'DONE',
        'CLOUD',
        'confirmed',
    )
    with pytest.raises(FleetError) as ended:
        online.confirm(ROBOT, confirm_id, reject=True)
    with pytest.raises(FleetError) as unknown:
        online.confirm(ROBOT, 'nobody')
    assert ended.value.code == 'not_waiting' and 'ended DONE' in str(ended.value)
    assert unknown.value.code == 'unknown_task_id' and "'nobody'" in str(unknown.value)


def test_a_confirm_names_who_answered_as_a_start_does(online: FleetClient) -> None:
    events: list[dict[str, Any]] = []
    online.on_event(lambda _, event: events.append(event))
    step = {'task_name': 'system/confirm', 'task_data': {'prompt': 'Load the tray'}}
    mission = online.start_mission(ROBOT, [step])
    (confirm_id,) = mission.accepted()['subtask_ids']
    wait_until(
        lambda: [e for e in events if e['task']['task_id'] == confirm_id and e['task']['feedback']],
        'the prompt as feedback',
    )
    with pytest.raises(FleetError) as claimed:  # another door's source: nothing answered
        online.confirm(ROBOT, confirm_id, source='WEB:boss')
    assert (claimed.value.code, 'source' in str(claimed.value)) == ('invalid_request', True)

    confirmed = online.confirm(ROBOT, confirm_id, source='alice')

    assert confirmed['by'] == 'CLOUD:alice'
    assert check(mission.result(), 'task')['status'] == 'DONE'
    (stored,) = online.history(ROBOT, task_name='system/confirm')
    assert stored['result']['by'] == 'CLOUD:alice'


def changes_of(events: list[dict[str, Any]], task_id: str) -> list[tuple[str, str]]:
    """(event, status) of a task's events, in order."""
    return [(e['event'], e['task']['status']) for e in events if e['task']['task_id'] == task_id]


def without_op(request: dict[str, Any]) -> dict[str, Any]:
    return {name: value for name, value in request.items() if name != 'op'}


def replied(received: list[Any], prefix: str) -> list[str]:
    """The request ids of the replies received to requests whose id starts with `prefix`."""
    ids = [json.loads(message.payload)['request_id'] for message in received]
    return [request_id for request_id in ids if request_id.startswith(prefix)]
