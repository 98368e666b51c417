"""Pause, resume and schedules over the gateway's REST API, against a real gateway process and
a real Task Manager node."""

from typing import Any

import httpx
import pytest

from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check

pytestmark = pytest.mark.ros


def test_pause_and_resume_a_mission_say_which_ids_and_why_not_the_others(
    robot: Robot, http: httpx.Client
) -> None:
    fib = {'task_name': 'fib', 'task_data': {'order': 1}}
    mission = {'subtasks': [fib, fib], 'task_id': 'm-1'}
    started = http.post('/api/missions', json=mission)
    assert started.status_code == 202, started.text
    (goal,) = robot.fib.wait_for_goals(1, TIMEOUT_SEC)

    paused = http.post('/api/tasks/pause', json={'task_ids': ['m-1', 'nope']})

    assert paused.status_code == 200, paused.text
    body = check(paused.json(), 'paused')
    assert body['paused'] == ['m-1']
    assert len(body['errors']) == 1 and "'nope'" in body['errors'][0]
    assert (body['task']['task_name'], body['task']['status']) == ('system/pause', 'ERROR')
    assert body['task']['source'] == 'WEB'
    assert check(http.get('/api/tasks/m-1').json(), 'task')['status'] == 'PAUSED'

    resumed = http.post('/api/tasks/resume', json={'task_ids': ['m-1']})

    body = check(resumed.json(), 'resumed')
    assert (resumed.status_code, body['resumed'], body['errors']) == (200, ['m-1'], [])
    assert body['task']['status'] == 'DONE'
    assert check(http.get('/api/tasks/m-1').json(), 'task')['status'] == 'IN_PROGRESS'
    again = check(http.post('/api/tasks/resume', json={'task_ids': ['m-1']}).json(), 'resumed')
    assert again['resumed'] == [] and len(again['errors']) == 1
    http.post('/api/tasks/cancel', json={'task_ids': ['m-1']})
    goal.succeed()


def test_schedules_are_added_listed_disabled_and_removed(http: httpx.Client) -> None:
    nightly = {
        'schedule_id': 'nightly',
        'task_name': 'fib',
        'task_data': {'order': 3},
        'cron': '0 2 * * *',
        'time_zone': 'Europe/Paris',
        'priority': 3,
        'timeout_sec': 60,
    }
    once = {
        'schedule_id': 'later',
        'subtasks': [{'task_name': 'instant', 'task_data': {'data': True}}],
        'delay_sec': 3600,
    }

    added = [http.post('/api/schedules', json=body) for body in (nightly, once)]

    for response in added:
        body = check(response.json(), 'scheduled')
        assert (response.status_code, body['scheduled']) == (200, True), response.text
        assert body['next_run'] and body['task']['status'] == 'DONE'
        assert body['task']['source'] == 'WEB'
    listed = http.get('/api/schedules')
    assert listed.status_code == 200
    by_id = {s['schedule_id']: check(s, 'schedule') for s in listed.json()}
    assert set(by_id) == {'nightly', 'later'}
    schedule = by_id['nightly']
    assert (schedule['task_name'], schedule['task_data'], schedule['cron']) == (
        'fib',
        {'order': 3},
        '0 2 * * *',
    )
    assert schedule['options'] == {'priority': 3, 'timeout_sec': 60}
    assert schedule['enabled'] and schedule['next_run'] and schedule['created_by'] == 'WEB'
    assert (schedule['last_status'], schedule['run_count']) == (None, 0)
    assert by_id['later']['task_name'] == 'system/mission'

    disabled = http.patch('/api/schedules/nightly', json={'enabled': False})

    body = check(disabled.json(), 'schedule')
    assert (disabled.status_code, body['enabled'], body['next_run']) == (200, False, None)
    enabled = check(http.patch('/api/schedules/nightly', json={'enabled': True}).json(), 'schedule')
    assert enabled['enabled'] and enabled['next_run']

    removed = http.delete('/api/schedules/nightly')

    assert removed.status_code == 200
    task = check(removed.json(), 'task')
    assert (task['task_name'], task['status']) == ('system/unschedule', 'DONE')
    assert [s['schedule_id'] for s in http.get('/api/schedules').json()] == ['later']


class TestRequestsRefused:
    """Requests refused: the tests share one node and one gateway (each test of this file starts
    both otherwise, ~1.6 s of CPU), none of them leaves a schedule or a task behind."""

    @pytest.fixture
    def http(self, class_http: httpx.Client) -> httpx.Client:
        return class_http

    def test_a_schedule_the_task_manager_refuses_is_no_http_error(self, http: httpx.Client) -> None:
        response = http.post('/api/schedules', json={'task_name': 'no/such_task', 'period_sec': 60})

        assert response.status_code == 200
        body = check(response.json(), 'scheduled')
        assert body['scheduled'] is False and body['next_run'] is None
        assert 'no/such_task' in body['message']
        assert body['task']['status'] == 'ERROR'
        assert http.get('/api/schedules').json() == []

    def test_an_unknown_schedule_id_is_404(self, http: httpx.Client) -> None:
        responses = [
            http.patch('/api/schedules/nope', json={'enabled': False}),
            http.delete('/api/schedules/nope'),
            http.delete('/api/schedules/bad%E2%80%AEid'),  # refused text: looked up nowhere
        ]

        for response in responses:
            error = check(response.json(), 'error')['error']
            assert (response.status_code, error['code']) == (404, 'unknown_schedule_id')
        assert "'nope'" in responses[0].json()['error']['message']

    @pytest.mark.parametrize(
        ('method', 'path', 'body', 'field', 'words'),
        [
            ('POST', '/api/tasks/pause', {}, 'task_ids', 'Field required'),
            ('POST', '/api/tasks/resume', {'task_ids': []}, 'task_ids', 'at least 1'),
            ('POST', '/api/tasks/pause', {'task_ids': ['a'], 'source': 'X'}, 'source', 'gateway'),
            ('POST', '/api/schedules', {'task_name': 'fib', 'period_sec': -1}, 'period_sec', '0'),
            (
                'POST',
                '/api/schedules',
                {'task_name': 'fib', 'at': '2030-01-01T02:00'},
                'at',
                'zone',
            ),
            (
                'POST',
                '/api/schedules',
                {'task_name': 'fib', 'cron': '1 2 * * *', 'overlap': 'NO'},
                'overlap',
                'SKIP',
            ),
            ('POST', '/api/schedules', {'task_name': 'fib'}, '', 'exactly one of at'),
            ('POST', '/api/schedules', {'delay_sec': 5}, '', 'task_name'),
            ('PATCH', '/api/schedules/x', {'enabled': 'yes'}, 'enabled', 'boolean'),
            ('PATCH', '/api/schedules/x', {}, 'enabled', 'Field required'),
        ],
    )
    def test_an_invalid_body_is_a_422_naming_the_field(
        self,
        http: httpx.Client,
        method: str,
        path: str,
        body: dict[str, Any],
        field: str,
        words: str,
    ) -> None:
        response = http.request(method, path, json=body)

        assert response.status_code == 422, response.text
        error = check(response.json(), 'error')['error']
        assert (error['code'], error['field']) == ('invalid_request', field)
        assert words in error['message']
        assert http.get('/api/schedules').json() == []

    @pytest.mark.parametrize('headers', [{}, {'Authorization': 'Bearer wrong'}])
    def test_without_the_token_nothing_is_paused_or_scheduled_401(
        self, http: httpx.Client, headers: dict[str, str]
    ) -> None:
        with httpx.Client(base_url=str(http.base_url), headers=headers) as stranger:
            responses = [
                stranger.post('/api/tasks/pause', json={'task_ids': ['x']}),
                stranger.post('/api/tasks/resume', json={'task_ids': ['x']}),
                stranger.get('/api/schedules'),
                stranger.post('/api/schedules', json={'task_name': 'fib', 'period_sec': 60}),
                stranger.patch('/api/schedules/x', json={'enabled': False}),
                stranger.delete('/api/schedules/x'),
            ]

        assert [r.status_code for r in responses] == [401] * len(responses)
        assert all(check(r.json(), 'error')['error']['code'] == 'unauthorized' for r in responses)
        assert http.get('/api/schedules').json() == []
