"""The console's doors (issue 38, item 3) on simulated robots: `task-manager-console` as users run
it, on a real mosquitto and the fleet history on SQLite and PostgreSQL; the robots, the history
(filters, CSV, bounds), the event stream, the metrics (read with prometheus_client's own
parser), the refusals of a start no robot can take, and the web gateway's doors it shares."""

import csv
import io
import json
from collections.abc import Callable, Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import httpx
import pytest
from prometheus_client.parser import text_string_to_metric_families
from task_manager_mqtt.testing import BrokerProcess
from task_manager_web.doors_testing import VIEWER

from task_manager.core.bounds import FLEET_HISTORY_ROWS_MAX
from task_manager_console.doors_testing import OPERATOR, ConsoleProcess, EventReader, wait_for
from task_manager_console.simulation.robot import SimulatedRobot

Document = dict[str, Any]
# key: (sample name, its labels as sorted pairs), value: the sample's value
Samples = dict[tuple[str, tuple[tuple[str, str], ...]], float]


@pytest.fixture
def sqlite_url(tmp_path: Path) -> str:
    return f'sqlite:///{tmp_path / "fleet.sqlite"}'


@pytest.fixture
def start_console(broker: BrokerProcess, tmp_path: Path) -> Iterator[Callable[..., ConsoleProcess]]:
    """Start `task-manager-console` on the test's broker and a database; stopped at the end
    (cleanly: exit code 0)."""
    consoles: list[ConsoleProcess] = []

    def start(database_url: str, *args: str) -> ConsoleProcess:
        console = ConsoleProcess(broker, database_url, tmp_path / f'console{len(consoles)}', *args)
        consoles.append(console)
        return console

    yield start
    for console in consoles:
        assert console.stop() == 0, '\n'.join(console.lines)


def task(task_id: str, status: str = 'IN_PROGRESS', **fields: Any) -> Document:
    """An active Task document."""
    return {
        'task_id': task_id, 'task_name': 'fib', 'source': 'CLOUD', 'status': status,
        'received': datetime.now(UTC).isoformat(), **fields,
    }  # fmt: skip


def robots_by_id(http: httpx.Client) -> dict[str, Document]:
    response = http.get('/api/robots')
    assert response.status_code == 200, response.text
    return {robot['robot_id']: robot for robot in response.json()}


def scrape(http: httpx.Client) -> Samples:
    response = http.get('/metrics')
    assert response.status_code == 200, response.text
    return {
        (sample.name, tuple(sorted(sample.labels.items()))): sample.value
        for family in text_string_to_metric_families(response.text)
        for sample in family.samples
    }


# ---- robots ----------------------------------------------------------------------------------


def test_the_robots_are_listed_each_with_its_state_queue_and_silence(
    broker: BrokerProcess,
    start_robot_on: Callable[..., SimulatedRobot],
    start_console: Callable[..., ConsoleProcess],
    sqlite_url: str,
) -> None:
    console = start_console(sqlite_url)
    busy = start_robot_on('robot1', tasks=('fib', 'dock'))
    busy.set_active([task('a'), task('b', 'QUEUED'), task('c', 'QUEUED'), task('d', 'PAUSED')])
    start_robot_on('robot2').go_offline()
    start_robot_on('robot3').vanish()  # its last will: CONNECTIONBROKEN

    with console.client(VIEWER) as http:
        robots = wait_for(
            lambda: robots_by_id(http),
            lambda r: (
                [r.get(i, {}).get('connection_state') for i in ('robot1', 'robot2', 'robot3')]
                == ['ONLINE', 'OFFLINE', 'CONNECTIONBROKEN']
                and len(r['robot1']['active']) == 4
            ),
            'three robots, each in its state',
        )
        listed = http.get('/api/robots').json()
        one = http.get('/api/robots/robot1')
        unknown = http.get('/api/robots/robot9')
        bad = http.get('/api/robots/robot%07')

    assert [r['robot_id'] for r in listed] == ['robot1', 'robot2', 'robot3']
    robot1 = robots['robot1']
    assert {t['task_name'] for t in robot1['tasks']} == {'fib', 'dock'}
    assert [t['task_id'] for t in robot1['active']] == ['a', 'b', 'c', 'd']
    assert (robot1['queue_length'], robot1['silent'], robot1['last_result']) == (2, False, None)
    assert robot1['since'] and datetime.fromisoformat(robot1['since']).tzinfo is not None
    assert (robots['robot2']['silent'], robots['robot3']['silent']) == (False, True)
    assert one.status_code == 200 and one.json()['robot_id'] == 'robot1'
    assert one.json()['active'] == robot1['active']
    assert (unknown.status_code, unknown.json()['error']['code']) == (404, 'unknown_robot')
    assert (bad.status_code, bad.json()['error']['code']) == (422, 'invalid_request')
    assert bad.json()['error']['field'] == 'robot_id'


# ---- the fleet history -----------------------------------------------------------------------


def test_the_history_filters_by_robot_task_name_status_source_and_time_and_exports_csv(
    start_robot_on: Callable[..., SimulatedRobot],
    start_console: Callable[..., ConsoleProcess],
    database_url: str,
) -> None:
    console = start_console(database_url)
    one, two = start_robot_on('robot1'), start_robot_on('robot2')
    early = datetime.now(UTC) - timedelta(hours=1)
    one.send_results(1, task_id='old', ended=early.isoformat())
    one.send_results(2, task_name='dock', status='ERROR', source='CLOUD:alice')
    two.send_results(3)
    two.send_results(1, task_id='=HYPERLINK("x")')

    with console.client(VIEWER) as http:
        everything = wait_for(
            lambda: http.get('/api/history').json(), lambda h: len(h) == 7, 'every result'
        )

        def ids(**query: Any) -> list[tuple[str, int]]:
            response = http.get('/api/history', params=query)
            assert response.status_code == 200, response.text
            return [(t['robot_id'], t['sequence']) for t in response.json()]

        by_robot = ids(robot_id='robot1')
        by_name = ids(task_name='dock')
        by_status_and_source = ids(status='ERROR', source='CLOUD:alice')
        by_task = ids(task_id='old')
        since = ids(ended_after=(early + timedelta(minutes=1)).isoformat(), robot_id='robot1')
        before = ids(ended_before=(early + timedelta(minutes=1)).isoformat())
        limited = ids(limit=2)
        exported = http.get('/api/history', params={'format': 'csv', 'robot_id': 'robot2'})

    assert everything[0]['ended'] >= everything[-1]['ended']  # newest first
    assert everything[-1]['task_id'] == 'old'
    assert by_robot == [('robot1', 3), ('robot1', 2), ('robot1', 1)]
    assert by_name == by_status_and_source == [('robot1', 3), ('robot1', 2)]
    assert by_task == before == [('robot1', 1)]
    assert since == [('robot1', 3), ('robot1', 2)]
    assert limited == [(r['robot_id'], r['sequence']) for r in everything[:2]]
    assert exported.status_code == 200
    assert exported.headers['content-type'].startswith('text/csv')
    assert 'filename="fleet_history.csv"' in exported.headers['content-disposition']
    rows = list(csv.DictReader(io.StringIO(exported.text)))
    assert [(r['robot_id'], r['sequence']) for r in rows] == [
        ('robot2', str(n)) for n in (4, 3, 2, 1)
    ]
    assert rows[0]['task_id'] == '\'=HYPERLINK("x")'  # a formula, quoted as text
    assert json.loads(rows[1]['result']) == {'sequence': [0, 1, 1]}


def test_a_history_query_beyond_its_bounds_is_refused_naming_the_field(
    start_robot_on: Callable[..., SimulatedRobot],
    start_console: Callable[..., ConsoleProcess],
    sqlite_url: str,
) -> None:
    console = start_console(sqlite_url, '--max-history-bytes', '2000')
    start_robot_on('robot1').send_results(5)
    with console.client(VIEWER) as http:
        wait_for(lambda: http.get('/api/history?limit=1').json(), len, 'a result stored')
        wait_for(lambda: robots_by_id(http)['robot1']['results_stored'], lambda n: n == 5, '5')
        refused = {
            'limit': http.get('/api/history', params={'limit': FLEET_HISTORY_ROWS_MAX + 1}),
            'task_name': http.get('/api/history', params={'task_name': 'fib\x1b[2J'}),
            'status': http.get('/api/history', params={'status': 'RUNNING'}),
            'ended_after': http.get('/api/history', params={'ended_after': 'yesterday'}),
            'sort': http.get('/api/history', params={'sort': 'name'}),
        }
        too_large = http.get('/api/history')

    for field, response in refused.items():
        assert response.status_code == 422, (field, response.text)
        assert response.json()['error']['code'] == 'invalid_request'
        assert response.json()['error']['field'] == field
    assert f'{FLEET_HISTORY_ROWS_MAX}' in refused['limit'].json()['error']['message']
    assert 'U+001B' in refused['task_name'].json()['error']['message']
    assert too_large.status_code == 422
    error = too_large.json()['error']
    assert (error['code'], error['field']) == ('reply_too_large', 'limit')
    assert 'the answer (5 tasks) would be' in error['message']
    assert 'page on with ended_before' in error['message']


# ---- the event stream ------------------------------------------------------------------------


def test_the_event_stream_says_hello_with_the_robots_then_each_result_and_robot_change(
    start_robot_on: Callable[..., SimulatedRobot],
    start_console: Callable[..., ConsoleProcess],
    sqlite_url: str,
) -> None:
    console = start_console(sqlite_url)
    robot = start_robot_on('robot1')
    with console.client(VIEWER) as http:
        wait_for(lambda: robots_by_id(http), lambda r: 'robot1' in r, 'robot1 seen')
    events = EventReader(console, VIEWER)
    try:
        [(kind, hello)] = events.wait(lambda e: e[:1], 'hello')
        sent = robot.send_results(3)
        results = events.wait(
            lambda e: (r := [d for k, d in e if k == 'result'])[2:] and r, 'three results'
        )
        robot.go_offline()
        offline = events.wait(
            lambda e: [d for k, d in e if k == 'robot' and d['connection_state'] == 'OFFLINE'],
            'robot1 OFFLINE',
        )
        console.stop()
        bye = events.wait(lambda e: [d for k, d in e if k == 'bye'], 'the stream ended')
    finally:
        events.close()

    assert events.headers['content-type'].startswith('text/event-stream')
    assert kind == 'hello'
    assert [r['robot_id'] for r in hello['robots']] == ['robot1']
    assert hello['robots'][0]['connection_state'] == 'ONLINE' and hello['database_up'] is True
    assert [(r['robot_id'], r['task_id']) for r in results] == [
        ('robot1', t['task_id']) for t in sent
    ]
    assert offline[-1]['robot_id'] == 'robot1' and offline[-1]['silent'] is False
    robot_states = [d for k, d in events.events if k == 'robot']
    assert robot_states[0]['last_result']['sequence'] >= 1  # the state after a result stored
    assert bye == [{'message': 'the console stops'}]


# ---- metrics ---------------------------------------------------------------------------------


def test_the_metrics_have_a_series_per_robot_and_the_fleet_historys(
    start_robot_on: Callable[..., SimulatedRobot],
    start_console: Callable[..., ConsoleProcess],
    sqlite_url: str,
) -> None:
    console = start_console(sqlite_url)
    busy = start_robot_on('robot1')
    busy.set_active([task('a'), task('b', 'QUEUED'), task('c', 'PAUSED')])
    busy.send_results(2)
    busy.send_results(1, status='ERROR')
    start_robot_on('robot2').go_offline()
    with console.client(VIEWER) as http:
        wait_for(
            lambda: robots_by_id(http),
            lambda r: (
                r.get('robot2', {}).get('connection_state') == 'OFFLINE'
                and r['robot1']['results_stored'] == 3
                and len(r['robot1']['active']) == 3
            ),
            'both robots, and three results',
        )
        http.get('/api/robots/robot9')
        samples = scrape(http)

    def value(name: str, **labels: str) -> float:
        return samples[(name, tuple(sorted(labels.items())))]

    prefix = 'task_manager_console'
    assert value(f'{prefix}_robots') == 2
    assert value(f'{prefix}_robot_connection', robot_id='robot1', state='ONLINE') == 1
    assert value(f'{prefix}_robot_connection', robot_id='robot1', state='OFFLINE') == 0
    assert value(f'{prefix}_robot_connection', robot_id='robot2', state='OFFLINE') == 1
    assert value(f'{prefix}_robot_online', robot_id='robot1') == 1
    assert value(f'{prefix}_robot_online', robot_id='robot2') == 0
    assert value(f'{prefix}_robot_active_tasks', robot_id='robot1') == 3
    assert value(f'{prefix}_robot_queued_tasks', robot_id='robot1') == 1
    assert value(f'{prefix}_robot_paused_tasks', robot_id='robot1') == 1
    assert value(f'{prefix}_robot_results_stored_total', robot_id='robot1') == 3
    assert value(f'{prefix}_tasks_ended_total', robot_id='robot1', status='DONE') == 2
    assert value(f'{prefix}_tasks_ended_total', robot_id='robot1', status='ERROR') == 1
    assert value(f'{prefix}_results_stored_total') == 3
    assert value(f'{prefix}_database_up') == 1
    assert value(f'{prefix}_results_waiting') == 0
    missed = {'route': '/api/robots/{robot_id}', 'method': 'GET', 'status': '404'}
    assert value(f'{prefix}_requests_total', **missed) == 1


# ---- a start no robot can take ---------------------------------------------------------------


def test_a_start_no_robot_can_take_is_refused_saying_why_for_each(
    start_robot_on: Callable[..., SimulatedRobot],
    start_console: Callable[..., ConsoleProcess],
    sqlite_url: str,
) -> None:
    console = start_console(sqlite_url)
    start_robot_on('robot1', tasks=('dock',))
    start_robot_on('robot2').go_offline()
    start_robot_on('robot3').set_connection('ONLINE', task_manager_connected=False)
    fib = {'task_name': 'fib', 'task_data': {'order': 3}}
    with console.client(OPERATOR) as http:
        wait_for(
            lambda: robots_by_id(http),
            lambda r: (
                r.get('robot2', {}).get('connection_state') == 'OFFLINE'
                and r.get('robot3', {}).get('silent')
                and 'robot1' in r
            ),
            'three robots',
        )
        anyone = http.post('/api/fleet/start', json=fib)
        named_offline = http.post('/api/fleet/start', json={**fib, 'robots': ['robot2']})
        named_unknown = http.post('/api/fleet/start', json={**fib, 'robots': ['robot9']})
        named_bad = http.post('/api/fleet/start', json={**fib, 'robots': ['robot1', 'r\x00']})
        on_offline = http.post('/api/robots/robot2/tasks/start', json=fib)
        on_unknown = http.post('/api/robots/robot9/tasks/start', json=fib)

    assert anyone.status_code == 409, anyone.text
    assert anyone.json()['error'] == {
        'code': 'no_robot',
        'message': 'no ONLINE robot declares fib (robot1: does not declare fib; robot2: '
        'OFFLINE; robot3: ONLINE but its bridge reaches no Task Manager)',
        'field': 'task_name',
    }
    assert named_offline.status_code == 409
    offline = named_offline.json()['error']
    assert (offline['code'], offline['field']) == ('robot_offline', 'robots.0')
    assert offline['message'].startswith('robot robot2 is OFFLINE since 20')
    assert (named_unknown.status_code, named_unknown.json()['error']['code']) == (
        404,
        'unknown_robot',
    )
    assert named_bad.status_code == 422
    assert named_bad.json()['error']['field'] == 'robots.1'
    assert (on_offline.status_code, on_offline.json()['error']['code']) == (409, 'robot_offline')
    assert (on_unknown.status_code, on_unknown.json()['error']['code']) == (404, 'unknown_robot')


# ---- the doors it shares with the web gateway ------------------------------------------------


def test_the_console_refuses_at_the_door_as_the_web_gateway_does(
    start_console: Callable[..., ConsoleProcess], sqlite_url: str
) -> None:
    console = start_console(sqlite_url)
    deep = '{"task_name": "fib", "task_data": ' + '[' * 40 + ']' * 40 + '}'
    with console.client(OPERATOR) as http, console.client(None) as nobody:
        health = nobody.get('/api/health')
        no_token = nobody.get('/api/robots')
        wrong_host = http.get('/api/robots', headers={'Host': 'evil.example.com'})
        too_large = http.post('/api/fleet/start', content=b'{' + b' ' * 1_048_576 + b'}')
        too_deep = http.post(
            '/api/fleet/start', content=deep, headers={'Content-Type': 'application/json'}
        )
        source = http.post('/api/fleet/start', json={'task_name': 'fib', 'source': 'WEB'})
        whoami = http.get('/api/whoami')

    assert health.status_code == 200
    assert health.json() == {
        'database_up': True, 'robots': 0, 'online': 0, 'results_waiting': 0, 'event_streams': 0
    }  # fmt: skip
    for response in (health, no_token, wrong_host, too_large):
        assert response.headers['x-frame-options'] == 'DENY'
        assert "frame-ancestors 'none'" in response.headers['content-security-policy']
    assert (no_token.status_code, no_token.json()['error']['code']) == (401, 'unauthorized')
    assert no_token.headers['www-authenticate'] == 'Bearer'
    assert (wrong_host.status_code, wrong_host.json()['error']['code']) == (
        400,
        'host_not_allowed',
    )
    assert (too_large.status_code, too_large.json()['error']['code']) == (413, 'body_too_large')
    assert (too_deep.status_code, too_deep.json()['error']['code']) == (422, 'nesting_too_deep')
    assert source.status_code == 422 and source.json()['error']['field'] == 'source'
    assert whoami.json() == {'role': 'operator', 'name': 'alice'}
