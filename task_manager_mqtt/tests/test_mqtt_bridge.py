"""The bridge between a real Task Manager and a real mosquitto, driven by the FleetClient
(and by a bare client, for what the FleetClient never sends)."""

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any, cast

import pytest

from task_manager.client import TaskManagerClient
from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check, wait_until
from task_manager.testing.harness import RosHarness
from task_manager.testing.lost_events import batch_writer, event_batch, flood_while_stopped
from task_manager_mqtt.fleet_client import FleetClient
from task_manager_mqtt.fleet_types import FleetError
from task_manager_mqtt.settings import (
    DEFAULT_MAX_PAYLOAD_BYTES,
    DEFAULT_PREFIX,
    PACKET_HEADROOM_BYTES,
)
from task_manager_mqtt.testing import (
    ROBOT,
    TESTER,
    BridgeProcess,
    BrokerProcess,
    RawClient,
    Received,
)
from task_manager_mqtt.topics import Topics

pytestmark = pytest.mark.ros
BURST = 200
BRIDGE_MAX_BYTES = 65_536
DEEP = b'[' * 5000 + b']' * 5000  # 10 KB: RecursionError in json and in a pydantic model
# each: its payload, and the error code of its reply (None: a dead letter, it has no usable id)
POISON: list[tuple[bytes, str | None]] = [
    (b'{"request_id": "p-deep", "op": "start_task", "task_name": "instant", "task_data": %s}'
     % DEEP, 'nesting_too_deep'),
    (DEEP, None),
    (json.dumps({'request_id': 'p-huge', 'op': 'stop', 'pad': 'x' * BRIDGE_MAX_BYTES}).encode(),
     'payload_too_large'),
    (b'{"request_id": "p-utf8", "op": "stop", "note": "\xff\xfe"}', 'invalid_request'),
    (b'\xff\xfe\x00\x01 not UTF-8', None),
    (b'{"request_id": "p-json", "op": "stop", ', 'invalid_request'),
    (b'not JSON at all', None),
    (b'', None),
    (b'{"op": "stop"}', None),
    (b'{"request_id": 42, "op": "stop"}', None),
    (b'{"request_id": ["p-list"], "op": "stop"}', None),
]  # fmt: skip
ROUNDS = 3
"""30 messages: more than mosquitto's in-flight window (20) of messages not acknowledged."""


def test_a_task_and_a_mission_from_the_cloud(online: FleetClient) -> None:
    events: list[dict[str, Any]] = []
    online.on_event(lambda robot_id, event: events.append(check(event, 'task_event')))
    task = online.start_task(ROBOT, 'instant', {'data': True})
    reply = check(task.accepted(), 'mqtt_reply')
    assert reply['ok'] and reply['task_id'] == task.task_id and not reply['duplicate']
    result = check(task.result(), 'task')
    assert (result['task_id'], result['status'], result['source']) == (
        task.task_id,
        'DONE',
        'CLOUD',
    )
    assert result['sequence'] > 0 and result['result'] == {'success': True, 'message': ''}

    mission = online.start_mission(
        ROBOT, [{'task_name': 'instant', 'task_data': {'data': True}}] * 2
    )
    assert len(check(mission.accepted(), 'mqtt_reply')['subtask_ids']) == 2
    ended = mission.result()
    assert (ended['task_name'], ended['status']) == ('system/mission', 'DONE'), ended

    of_task = [e['event'] for e in events if e['task']['task_id'] == task.task_id]
    assert of_task == ['RECEIVED', 'STARTED', 'ENDED']
    robot = online.robots[ROBOT]
    check(robot.connection, 'mqtt_connection')
    assert {t['task_name'] for t in robot.tasks} >= {'fib', 'instant', 'system/mission'}


def test_a_start_has_the_bridges_source_never_another_doors(online: FleetClient) -> None:
    """CLOUD, or CLOUD:<the name the request's source gives> (issue 37, item 3: a start from
    the cloud claimed WEB:boss, Mission or schedule:nightly, and their source priorities)."""
    instant = {'task_name': 'instant', 'task_data': {'data': True}}
    unnamed = online.request(ROBOT, 'start_task', request_id='unnamed', source='', **instant)
    assert unnamed.result(TIMEOUT_SEC)['ok']
    named = {
        claimed: online.start_task(ROBOT, 'instant', {'data': True}, source=claimed)
        for claimed in ('CLOUD', 'alice', 'CLOUD:bob', 'Mission')
    }
    mission = online.start_mission(ROBOT, [instant], source='carol')
    refused = [
        online.request(ROBOT, 'start_task', request_id=f'claims-{index}', source=claimed,
                       **instant).result(TIMEOUT_SEC)
        for index, claimed in enumerate(['WEB:boss', 'schedule:nightly', 'CLOUD:WEB:boss', 'a b'])
    ]  # fmt: skip

    sources = {claimed: task.result()['source'] for claimed, task in named.items()}
    assert sources == {
        'CLOUD': 'CLOUD',
        'alice': 'CLOUD:alice',
        'CLOUD:bob': 'CLOUD:bob',
        'Mission': 'CLOUD:Mission',
    }
    assert mission.result()['source'] == 'CLOUD:carol'
    for reply in refused:
        error = check(reply, 'mqtt_reply')['error']
        assert not reply['ok'] and (error['code'], error['field']) == ('invalid_request', 'source')
        assert "source: the name of who asks (1 to 64 letters, digits, '.'" in error['message']
    stored = {t['task_id']: t['source'] for t in online.history(ROBOT, task_name='instant')}
    assert stored['unnamed'] == 'CLOUD'
    assert not [task_id for task_id in stored if task_id.startswith('claims-')]
    assert {s.partition(':')[0] for s in stored.values()} == {'CLOUD', 'Mission'}


def test_a_request_delivered_twice_starts_one_task(online: FleetClient) -> None:
    request: dict[str, Any] = {
        'task_name': 'fib',
        'task_data': {'order': 1},
        'request_id': 'cloud-42',
    }
    first = online.request(ROBOT, 'start_task', **request).result(TIMEOUT_SEC)
    again = check(online.request(ROBOT, 'start_task', **request).result(TIMEOUT_SEC), 'mqtt_reply')
    # without a task_id, the request_id is the task's id: the second is recognised
    assert first['ok'] and first['task_id'] == 'cloud-42' and not first['duplicate']
    assert again['ok'] and again['duplicate'] and again['task']['task_id'] == 'cloud-42'
    assert online.cancel(ROBOT, ['cloud-42'])['status'] == 'DONE'
    stored = online.history(ROBOT, source='CLOUD', task_name='fib')
    assert [t['task_id'] for t in stored] == ['cloud-42']
    # started again once it ended: the FleetTask has the ended task at once
    again_later = online.start_task(ROBOT, 'fib', {'order': 1}, task_id='cloud-42')
    assert again_later.accepted()['duplicate']
    assert again_later.result()['status'] == 'CANCELED'


def test_every_result_of_a_broker_outage_arrives_once_in_order(
    online: FleetClient, broker: BrokerProcess
) -> None:
    results: list[dict[str, Any]] = []
    online.on_result(lambda _, task: results.append(task))
    with TaskManagerClient('outage_test', timeout_sec=TIMEOUT_SEC) as client:
        client.wait_until_available()
        handles = [client.start_task('instant', {'data': True}) for _ in range(BURST // 2)]
        wait_until(lambda: len(results) >= BURST // 4, 'results before the outage')
        broker.stop()
        handles += [client.start_task('instant', {'data': True}) for _ in range(BURST // 2)]
        for handle in handles:
            assert handle.result(TIMEOUT_SEC).ok
        broker.start()
        wait_until(lambda: len(results) >= BURST, f'{BURST} results', timeout_sec=30)
    assert sorted(t['task_id'] for t in results) == sorted(h.task_id for h in handles)
    sequences = [t['sequence'] for t in results]
    assert sequences == sorted(sequences) and len(set(sequences)) == BURST


def test_a_restarted_bridge_sends_what_ended_meanwhile_and_nothing_again(
    online: FleetClient, bridge: BridgeProcess, start_bridge: Callable[..., BridgeProcess]
) -> None:
    first = online.start_task(ROBOT, 'instant', {'data': True})
    first.result()
    results: list[dict[str, Any]] = []
    online.on_result(lambda _, task: results.append(task))
    assert bridge.stop() == 0
    with TaskManagerClient('restart_test', timeout_sec=TIMEOUT_SEC) as client:
        ended = [client.run_task('instant', {'data': True}).task_id for _ in range(5)]
    start_bridge()
    wait_until(lambda: len(results) >= len(ended), 'the results that ended meanwhile')
    assert [t['task_id'] for t in results] == ended
    assert online.robots[ROBOT].duplicates == 0


def test_a_task_whose_end_went_missing_leaves_the_active_list(
    ros: RosHarness, online: FleetClient, bridge: BridgeProcess
) -> None:
    """The bridge stopped (SIGSTOP) while more batches of task events came than it keeps: the
    ENDED of a task among those lost never comes, so once it goes on the bridge reads the
    active list again from the node (the client logs how many batches went missing). Here
    `pre` is a task only the events knew (the test stands in for the node's writer): before,
    it stayed active for good."""
    writer = batch_writer(ros)
    writer.publish(event_batch('pre'))
    assert online.wait_for(lambda robots: _active_ids(robots) >= {'pre'}), 'pre never active'

    flood_while_stopped(writer, bridge.process.pid)

    bridge.wait_for_log(r'\d+ batch\(es\) of task events went missing', TIMEOUT_SEC)
    assert online.wait_for(lambda robots: 'pre' not in _active_ids(robots)), 'pre still active'


def _active_ids(robots: dict[str, Any]) -> set[str]:
    return {task['task_id'] for task in robots[ROBOT].active_tasks}


def _results_then_a_new_history(
    count: int,
    start_robot: Callable[[], Robot],
    start_bridge: Callable[..., BridgeProcess],
    fleet: FleetClient,
    folder: Path,
) -> list[dict[str, Any]]:
    """`count` results through the bridge, then both stopped and the robot started again with
    a new history file (its old one deleted), its bridge not; the results."""
    robot, bridge = start_robot(), start_bridge()
    assert fleet.wait_online([ROBOT], TIMEOUT_SEC)
    results = [fleet.start_task(ROBOT, 'instant', {'data': True}).result() for _ in range(count)]
    assert bridge.stop() == 0 and robot.process.stop() == 0
    for part in folder.glob('history.sqlite*'):
        part.unlink()
    start_robot()
    return results


def test_a_robot_whose_history_began_again_is_heard_by_the_cloud(
    start_robot: Callable[[], Robot],
    start_bridge: Callable[..., BridgeProcess],
    fleet: FleetClient,
    tmp_path: Path,
) -> None:
    """The robot restarted with a new history file (reinstalled, or its history moved): its
    results carry sequence numbers the cloud has had, with other tasks, and still reach it."""
    before = _results_then_a_new_history(3, start_robot, start_bridge, fleet, tmp_path)
    start_bridge()
    assert fleet.wait_online([ROBOT], TIMEOUT_SEC)

    after = fleet.start_task(ROBOT, 'instant', {'data': True}).result()

    assert after['status'] == 'DONE'
    assert after['sequence'] <= before[-1]['sequence']  # a number the cloud had


def test_a_new_history_that_grew_past_the_last_acknowledged_is_sent_from_its_start(
    start_robot: Callable[[], Robot],
    start_bridge: Callable[..., BridgeProcess],
    fleet: FleetClient,
    tmp_path: Path,
) -> None:
    """The robot restarted with a new history file while its bridge was away, and ended more
    tasks than the bridge had sent: the bridge's last acknowledged number is another task's
    there, so it sends the new history from its start, not from that number on."""
    _results_then_a_new_history(1, start_robot, start_bridge, fleet, tmp_path)
    with TaskManagerClient('new_history_test', timeout_sec=TIMEOUT_SEC) as client:
        ended = [client.run_task('instant', {'data': True}).task_id for _ in range(3)]
    results: list[dict[str, Any]] = []
    fleet.on_result(lambda _, task: results.append(task))

    start_bridge()

    wait_until(lambda: len(results) >= len(ended), 'the new history from its start')
    assert [(t['sequence'], t['task_id']) for t in results] == list(enumerate(ended, start=1))


def test_bad_requests_get_an_error_reply_and_start_nothing(
    online: FleetClient, broker: BrokerProcess
) -> None:
    unknown = check(online.request(ROBOT, 'dance').result(TIMEOUT_SEC), 'mqtt_reply')
    missing = check(online.request(ROBOT, 'start_task').result(TIMEOUT_SEC), 'mqtt_reply')
    assert not unknown['ok'] and unknown['error']['field'] == 'op'
    allowed = 'allowed: start_task, start_mission, cancel, stop, history'
    assert allowed in unknown['error']['message']
    assert not missing['ok'] and missing['error']['field'] == 'task_name'
    # over the bridge's limit: refused by the broker itself (its limit is the same)
    pad = 'x' * DEFAULT_MAX_PAYLOAD_BYTES
    with pytest.raises(FleetError, match='the broker takes at most') as refused:
        online.request(ROBOT, 'stop', pad=pad).result(TIMEOUT_SEC)  # not sent by the client
    assert refused.value.code == 'payload_too_large'
    with RawClient(broker.port, TESTER, broker.passwords[TESTER]) as raw:  # sent: disconnected
        over = 'x' * (DEFAULT_MAX_PAYLOAD_BYTES + PACKET_HEADROOM_BYTES)
        raw.publish(Topics(DEFAULT_PREFIX, ROBOT).request, over, wait=False)
        raw.wait_for(lambda _: 'Packet too large' in raw.disconnections, 'its disconnection')
    assert online.history(ROBOT, source='CLOUD') == []


def test_poison_messages_get_one_answer_each_and_the_robot_still_answers(
    robot: Robot,
    broker: BrokerProcess,
    start_bridge: Callable[..., BridgeProcess],
    fleet: FleetClient,
) -> None:
    """Retained requests too: refused when they come, never handed over again at a
    (re)connection; the history shows that none of them ran."""
    topics = Topics(DEFAULT_PREFIX, ROBOT)
    dead: list[dict[str, Any]] = []
    fleet.on_dead_letter(lambda robot_id, letter: dead.append(check(letter, 'mqtt_dead_letter')))
    with RawClient(broker.port, TESTER, broker.passwords[TESTER], topics=[topics.reply]) as raw:

        def send_poison() -> None:
            for _ in range(ROUNDS):
                for payload, _code in POISON:
                    assert raw.publish(topics.request, payload) == 'Success'
                # the retain flag on a request published while the bridge is subscribed
                raw.publish(topics.request, start_request('p-retained'), retain=True)

        def reply_to(request_id: str) -> dict[str, Any]:
            raw.publish(topics.request, json.dumps({'request_id': request_id, 'op': 'dance'}))
            reply = raw.wait_for(lambda received: replies_to(received, request_id), request_id)
            return cast(dict[str, Any], reply)

        # stored by the broker before the bridge's first subscription: never delivered
        stored = start_request('p-retained-stored')
        assert raw.publish(topics.request, stored, retain=True) == 'No matching subscribers'
        bridge = start_bridge('--max-payload-bytes', str(BRIDGE_MAX_BYTES))
        assert fleet.wait_online([ROBOT])
        send_poison()
        task = fleet.start_task(ROBOT, 'instant', {'data': True}, task_id='after-poison')
        assert task.accepted()['ok'] and task.result()['status'] == 'DONE'
        reply_to('p-end')  # the replies to all that came before are there
        expected = sorted([*(code for _, code in POISON if code), 'retained_request'] * ROUNDS)
        codes = [r['error']['code'] for r in replies_to(raw.received, 'p-')]
        assert sorted(codes) == sorted([*expected, 'invalid_request'])  # and p-end's
        unaddressed = sum(code is None for _, code in POISON) * ROUNDS
        assert fleet.wait_for(lambda robots: robots[ROBOT].dead_letters == unaddressed)
        assert [letter['count'] for letter in dead] == list(range(1, unaddressed + 1))
        assert {d['error']['code'] for d in dead} == {'invalid_request', 'nesting_too_deep'}

        # the same while the bridge is away: kept in its session, delivered when it is back
        assert bridge.stop() == 0
        send_poison()
        history = fleet.request(ROBOT, 'history', source='CLOUD')
        start_bridge('--max-payload-bytes', str(BRIDGE_MAX_BYTES))
        reply = check(history.result(TIMEOUT_SEC), 'mqtt_reply')
        reply_to('p-end-2')
        assert not replies_to(raw.received, 'p-retained-stored')
    assert reply['ok'] and [t['task_id'] for t in reply['tasks']] == ['after-poison'], reply
    assert len(dead) == 2 * unaddressed  # counted again from 1 by the new bridge


def start_request(task_id: str) -> str:
    request = {'request_id': task_id, 'op': 'start_task', 'task_name': 'instant',
               'task_data': {'data': True}, 'task_id': task_id}  # fmt: skip
    return json.dumps(request)


def replies_to(received: list[Received], prefix: str) -> list[dict[str, Any]]:
    """The replies received to requests whose id starts with `prefix`."""
    replies = [check(json.loads(m.payload), 'mqtt_reply') for m in received]
    return [r for r in replies if r['request_id'].startswith(prefix)]
