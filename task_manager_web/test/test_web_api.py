"""The gateway's REST API against a real gateway process and a real Task Manager node."""

import csv
import io
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import httpx
import jsonschema
import pytest
from test_msgs.action import Fibonacci

from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check

pytestmark = pytest.mark.ros


@pytest.fixture
def pool() -> Any:
    with ThreadPoolExecutor(4) as executor:
        yield executor


def start(http: httpx.Client, body: dict[str, Any], **params: Any) -> httpx.Response:
    return http.post('/api/tasks/start', json=body, params=params)


def started_in_background(
    pool: ThreadPoolExecutor, http: httpx.Client, body: dict[str, Any]
) -> Future[httpx.Response]:
    """Start with wait=true in a worker: the answer comes once the task ended."""
    return pool.submit(start, http, body, wait='true', timeout_sec=TIMEOUT_SEC)


def test_start_answers_at_once_with_the_id_then_wait_gives_the_end(
    robot: Robot, http: httpx.Client, pool: ThreadPoolExecutor
) -> None:
    response = start(http, {'task_name': 'fib', 'task_data': {'order': 4}, 'task_id': 'web-1'})

    assert response.status_code == 202
    assert check(response.json(), 'started')['task_id'] == 'web-1'
    (goal,) = robot.fib.wait_for_goals(1, TIMEOUT_SEC)
    assert goal.goal_handle.request.order == 4
    state = check(http.get('/api/tasks/web-1').json(), 'task')
    assert state['source'] == 'WEB' and state['status'] in ('RECEIVED', 'IN_PROGRESS')
    # the gateway says who started a task, not the request
    spoofed = [
        start(http, {'task_name': 'fib', 'task_id': 'spoofed', 'source': 'CLOUD'}),
        http.post('/api/missions', json={'subtasks': [{'task_name': 'fib'}], 'source': 'CLOUD'}),
    ]
    for response in spoofed:
        error = check(response.json(), 'error')['error']
        assert (response.status_code, error['field']) == (422, 'source')
        assert 'set by the gateway' in error['message']
    assert http.get('/api/tasks/spoofed').status_code == 404

    waiting = started_in_background(
        pool, http, {'task_name': 'fib', 'task_data': {'order': 2}, 'task_id': 'web-2'}
    )
    second = robot.fib.wait_for_goals(2, TIMEOUT_SEC)[1]
    second.succeed(Fibonacci.Result(sequence=[0, 1, 1]))
    ended = waiting.result(TIMEOUT_SEC)

    assert ended.status_code == 200
    body = check(ended.json(), 'started')
    assert body['ended'] is True
    task = body['task']
    assert (task['task_id'], task['status'], task['result']) == (
        'web-2',
        'DONE',
        {'sequence': [0, 1, 1]},
    )
    assert task['sequence'] > 0 and task['started'] and task['duration_sec'] >= 0
    goal.succeed()


def test_read_without_token_opens_reading_only(robot: Robot, start_gateway: Any) -> None:
    gateway = start_gateway('--read-without-token')
    with httpx.Client(base_url=gateway.url, timeout=TIMEOUT_SEC) as anonymous:
        assert anonymous.get('/api/history').status_code in (200, 503)
        assert anonymous.post('/api/tasks/start', json={'task_name': 'fib'}).status_code == 401


def test_cancel_and_stop_end_running_tasks_canceled(
    robot: Robot, http: httpx.Client, pool: ThreadPoolExecutor
) -> None:
    first = started_in_background(
        pool, http, {'task_name': 'fib', 'task_data': {'order': 1}, 'task_id': 'to-cancel'}
    )
    second = started_in_background(
        pool, http, {'task_name': 'fib', 'task_data': {'order': 1}, 'task_id': 'to-stop'}
    )
    robot.fib.wait_for_goals(2, TIMEOUT_SEC)

    cancel = http.post('/api/tasks/cancel', json={'task_ids': ['to-cancel']})

    assert cancel.status_code == 200
    assert check(cancel.json(), 'task')['status'] == 'DONE' and cancel.json()['source'] == 'WEB'
    assert first.result(TIMEOUT_SEC).json()['task']['status'] == 'CANCELED'
    stop = http.post('/api/stop')
    assert check(stop.json(), 'task')['task_name'] == 'system/stop'
    assert stop.json()['source'] == 'WEB'
    assert second.result(TIMEOUT_SEC).json()['task']['status'] == 'CANCELED'


def test_a_mission_runs_its_subtasks_in_turn(
    robot: Robot, http: httpx.Client, pool: ThreadPoolExecutor
) -> None:
    body = {
        'subtasks': [
            {'task_name': 'fib', 'task_data': {'order': 1}},
            {'task_name': 'instant', 'task_data': {'data': True}},
            {'task_name': 'fib', 'task_data': {'order': 2}},
        ],
        'task_id': 'web-mission',
    }
    waiting = pool.submit(
        http.post, '/api/missions', json=body, params={'wait': 'true', 'timeout_sec': TIMEOUT_SEC}
    )

    robot.fib.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    robot.fib.wait_for_goals(2, TIMEOUT_SEC)[1].succeed()
    response = waiting.result(TIMEOUT_SEC)

    assert response.status_code == 200
    started = check(response.json(), 'started')
    assert started['task']['status'] == 'DONE' and len(started['subtask_ids']) == 3
    assert [g.goal_handle.request.order for g in robot.fib.goals.items] == [1, 2]
    subtask = check(http.get(f'/api/tasks/{started["subtask_ids"][1]}').json(), 'task')
    assert (subtask['task_name'], subtask['mission_id']) == ('instant', 'web-mission')


def test_history_filters_and_csv_export(http: httpx.Client) -> None:
    for _ in range(3):
        response = start(http, {'task_name': 'instant', 'task_data': {'data': True}}, wait='true')
        assert response.json()['task']['status'] == 'DONE', response.text
    formula = '=HYPERLINK("http://example.com","x")'  # run by a spreadsheet unless quoted
    refused = start(http, {'task_name': 'no/such_task', 'task_id': formula}, wait='true')
    assert refused.status_code == 200

    done = http.get('/api/history', params={'task_name': 'instant', 'status': 'DONE'}).json()
    errors = http.get('/api/history', params={'status': 'ERROR', 'limit': 1}).json()
    exported = http.get('/api/history', params={'format': 'csv'})

    assert [check(t, 'task')['status'] for t in done] == ['DONE'] * 3
    assert [t['task_name'] for t in errors] == ['no/such_task']
    sequences = [t['sequence'] for t in done]
    assert sequences == sorted(sequences, reverse=True)
    assert exported.headers['content-type'].startswith('text/csv')
    rows = list(csv.DictReader(io.StringIO(exported.text)))
    assert len(rows) == 4 and {r['source'] for r in rows} == {'WEB'}
    assert rows[0]['task_name'] == 'no/such_task' and rows[0]['error_code'] == 'unknown_task'
    assert rows[0]['task_id'] == f"'{formula}"
    invalid = http.get('/api/history', params={'status': 'RUNNING'})
    assert invalid.status_code == 422 and invalid.json()['error']['field'] == 'status'


def test_without_a_node_the_answer_is_503_at_once(start_gateway: Any) -> None:
    gateway = start_gateway()
    with httpx.Client(
        base_url=gateway.url, headers={'Authorization': f'Bearer {gateway.token}'}, timeout=2.0
    ) as http:
        health = http.get('/api/health').json()
        responses = [
            http.get('/api/active'),
            http.post('/api/tasks/start', json={'task_name': 'fib'}),
            http.get('/api/tasks'),
        ]

    assert (health['connected'], health['events']) == (False, False)
    for response in responses:
        assert response.status_code == 503
        assert 'not reachable' in check(response.json(), 'error')['error']['message']


def test_openapi_and_docs_are_served_without_any_cdn(gateway: Any, tmp_path: Path) -> None:
    with httpx.Client(base_url=gateway.url) as http:
        spec = http.get('/openapi.json').json()
        docs = http.get('/docs').text
        dashboard = http.get('/').text

    assert {'/api/tasks/start', '/api/missions', '/api/events', '/api/history'} <= set(
        spec['paths']
    )
    for page in (docs, dashboard):
        assert 'cdn' not in page.lower()
        assert 'https://' not in page


class TestRequestsRefusedOrRead:
    """Requests refused, or answered without a goal of `fib`: the tests share one node and one
    gateway (each test of this file starts both otherwise, ~1.6 s of CPU), none leaves a task
    running or a goal on `fib`."""

    @pytest.fixture
    def robot(self, class_robot: Robot) -> Robot:
        return class_robot

    @pytest.fixture
    def http(self, class_http: httpx.Client) -> httpx.Client:
        return class_http

    def test_declared_tasks_come_with_a_json_schema_of_their_goal_and_how_they_pause(
        self,
        http: httpx.Client,
    ) -> None:
        response = http.get('/api/tasks')

        assert response.status_code == 200
        tasks = {task['task_name']: check(task, 'declared_task') for task in response.json()}
        assert {'fib', 'instant', 'system/mission', 'system/stop'} <= set(tasks)
        fib = tasks['fib']
        assert fib['msg_interface'] == 'test_msgs/action/Fibonacci'
        assert fib['reentrant'] and fib['cancel_on_stop']
        assert (fib['pause'], tasks['system/mission']['pause']) == ('none', 'between_subtasks')
        order = fib['goal_schema']['properties']['order']
        assert order['type'] == 'integer' and order['x-ros-type'] == 'int32'
        assert (order['minimum'], order['maximum'], order['default']) == (-(2**31), 2**31 - 1, 0)
        jsonschema.Draft202012Validator.check_schema(fib['goal_schema'])
        subtask = tasks['system/mission']['goal_schema']['properties']['subtasks']
        assert subtask['type'] == 'array' and 'allow_skipping' in subtask['items']['properties']

    def test_a_refused_task_is_no_http_error_but_its_result(self, http: httpx.Client) -> None:
        response = start(http, {'task_name': 'no/such_task'}, wait='true')

        assert response.status_code == 200
        task = check(response.json(), 'started')['task']
        assert (task['status'], task['error_code']) == ('ERROR', 'unknown_task')
        assert 'no/such_task' in task['error_message']

    def test_bad_task_data_is_refused_by_the_node_naming_the_field(
        self, http: httpx.Client
    ) -> None:
        response = start(http, {'task_name': 'fib', 'task_data': {'order': 'many'}}, wait='true')

        task = check(response.json(), 'started')['task']
        assert (task['status'], task['error_code']) == ('ERROR', 'task_data_parsing_failed')
        assert "'order'" in task['error_message']

    @pytest.mark.parametrize(
        ('content', 'field', 'words'),
        [
            ('{"task_data": {}}', 'task_name', 'Field required'),
            ('{"task_name": "fib", "task_dat": {}}', 'task_dat', 'unknown field'),
            ('{"task_name": "fib", "task_data": [1]}', 'task_data', 'dictionary'),
            ('{"task_name": ', '', 'not valid JSON'),
            ('[1, 2]', '', 'JSON object'),
        ],
    )
    def test_an_invalid_body_is_a_422_naming_the_field_and_starts_nothing(
        self, robot: Robot, http: httpx.Client, content: str, field: str, words: str
    ) -> None:
        response = http.post(
            '/api/tasks/start', content=content, headers={'Content-Type': 'application/json'}
        )

        assert response.status_code == 422
        error = check(response.json(), 'error')['error']
        assert (error['code'], error['field']) == ('invalid_request', field)
        assert words in error['message']
        assert http.get('/api/active').json() == []

    def test_a_huge_body_is_refused_413(self, http: httpx.Client) -> None:
        body = {'task_name': 'fib', 'task_data': {'order': 1, 'padding': 'x' * 2_000_000}}

        response = start(http, body)

        assert response.status_code == 413
        assert check(response.json(), 'error')['error']['code'] == 'body_too_large'
        assert http.get('/api/active').json() == []

    @pytest.mark.parametrize('headers', [{}, {'Authorization': 'Bearer wrong'}])
    def test_without_the_token_nothing_starts_401(
        self, robot: Robot, http: httpx.Client, headers: dict[str, str]
    ) -> None:
        with httpx.Client(base_url=str(http.base_url), headers=headers) as stranger:
            responses = [
                stranger.post('/api/tasks/start', json={'task_name': 'fib', 'task_id': 'intruder'}),
                stranger.post('/api/stop'),
                stranger.post('/api/tasks/cancel', json={'task_ids': ['x']}),
                stranger.get('/api/active'),
                stranger.get('/api/events'),
            ]

        assert [r.status_code for r in responses] == [401] * len(responses)
        assert all(check(r.json(), 'error')['error']['code'] == 'unauthorized' for r in responses)
        assert http.get('/api/tasks/intruder').status_code == 404
        assert not robot.fib.goals.items

    def test_unknown_task_id_and_route_are_json_404(self, http: httpx.Client) -> None:
        unknown = http.get('/api/tasks/never-started')
        route = http.get('/api/nothing-here')
        body = {'task_name': 'instant', 'task_data': {'data': True}}
        assert start(http, body, wait='true', timeout_sec=TIMEOUT_SEC).status_code == 200
        # ROS would cut at the NUL: the newest task must not come back for it
        cut = [http.get(f'/api/tasks/{path}') for path in ('%00', '%00junk', 'a%0Ab')]

        assert [r.status_code for r in cut] == [404, 404, 404], [r.text for r in cut]
        assert unknown.status_code == 404 and check(unknown.json(), 'error')
        assert unknown.json()['error']['code'] == 'unknown_task_id'
        assert route.status_code == 404 and route.json()['error']['code'] == 'not_found'
