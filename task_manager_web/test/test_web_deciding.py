"""The gateway's API of what decides what runs (issue 29): a start's options, reprioritize and
why, against a real gateway process and a real Task Manager whose drive and dock share `base`."""

from collections.abc import Callable, Iterator
from typing import Any

import httpx
import pytest

from task_manager.testing.gateway import TIMEOUT_SEC, SharedBaseRobot, check
from task_manager_web.testing import GatewayProcess, gateway_client

pytestmark = pytest.mark.ros


@pytest.fixture
def http(base: SharedBaseRobot, gateway: GatewayProcess) -> Iterator[httpx.Client]:
    with gateway_client(gateway) as client:
        yield client


def start(http: httpx.Client, body: dict[str, Any], **params: Any) -> httpx.Response:
    return http.post('/api/tasks/start', json=body, params=params)


def test_a_start_with_options_queues_is_reprioritized_and_why_names_the_drive(
    base: SharedBaseRobot, http: httpx.Client
) -> None:
    drive = {'task_name': 'drive', 'task_data': {'order': 1}, 'task_id': 'drive-12', 'priority': 5}
    assert start(http, drive).status_code == 202
    base.probe.wait_in_progress('drive-12')

    queued = start(http, {'task_name': 'dock', 'task_id': 'dock-4', 'on_conflict': 'queue',
                          'task_data': {'order': 1}})  # fmt: skip
    base.probe.wait_active(lambda t: ('dock-4', 'QUEUED') in t)
    active = {t['task_id']: t for t in http.get('/api/active').json()}
    why = http.get('/api/tasks/dock-4/why')
    raised = http.post('/api/tasks/reprioritize', json={'task_ids': ['dock-4'], 'priority': 3})
    refused = start(
        http,
        {'task_name': 'dock', 'task_data': {'order': 1}, 'task_id': 'dock-3', 'priority': 1},
        wait='true',
    )
    why_refused = http.get('/api/tasks/dock-3/why')

    assert queued.status_code == 202
    dock = check(active['dock-4'], 'task')
    assert (dock['status'], dock['queue_position'], dock['priority']) == ('QUEUED', 1, 0)
    assert active['drive-12']['priority'] == 5
    assert why.status_code == 200
    (decision,) = [check(d, 'decision') for d in why.json()]
    assert (decision['decision'], decision['reason']) == (
        'queued',
        'queued behind drive-12 (priority 5), which holds base',
    )
    assert raised.status_code == 200
    change = check(raised.json(), 'task')
    assert (change['task_name'], change['status'], change['source']) == (
        'system/reprioritize',
        'DONE',
        'WEB',
    )
    assert change['result']['successful_changes'] == ['dock-4']
    assert http.get('/api/tasks/dock-4').json()['priority'] == 3
    task = check(refused.json(), 'started')['task']
    assert (task['status'], task['error_code']) == ('ERROR', 'preemption_refused')
    reason = "refused: priority 1 is below drive-12's 5, which holds base"
    assert [(d['decision'], d['reason']) for d in why_refused.json()] == [('refused', reason)]
    assert task['decisions'][-1]['reason'] == reason
    base.servers['drive'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    base.servers['dock'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    assert base.probe.wait_result_message('dock-4').task_status == 'DONE'
    trail = [d['decision'] for d in http.get('/api/tasks/dock-4/why').json()]
    assert trail == ['queued', 'reprioritized', 'started']


def test_a_timeout_of_a_start_or_a_mission_ends_it_error_timeout(
    base: SharedBaseRobot, http: httpx.Client
) -> None:
    body = {'task_name': 'drive', 'task_data': {'order': 1}, 'timeout_sec': 0.5}
    mission = {
        'subtasks': [{'task_name': 'dock', 'task_data': {'order': 1}, 'task_id': 'm-dock'}],
        'task_id': 'tour',
        'timeout_sec': 0.5,
    }

    ended = start(http, body, wait='true', timeout_sec=TIMEOUT_SEC)
    tour = http.post('/api/missions', json=mission, params={'wait': 'true'})

    task = check(ended.json(), 'started')['task']
    assert (task['status'], task['error_code']) == ('ERROR', 'timeout')
    assert http.get(f'/api/tasks/{task["task_id"]}/why').json()[-1]['decision'] == 'timeout'
    assert check(tour.json(), 'started')['task']['error_code'] == 'timeout'


class TestRequestsRefused:
    """Requests refused: the tests share one node and one gateway (each test of this file starts
    both otherwise, ~1.6 s of CPU); none starts a task."""

    @pytest.fixture
    def base(self, class_base: SharedBaseRobot) -> SharedBaseRobot:
        return class_base

    @pytest.fixture
    def http(self, class_base_http: httpx.Client) -> httpx.Client:
        return class_base_http

    @pytest.mark.parametrize(
        ('path', 'body', 'field'),
        [
            ('/api/tasks/start', {'task_name': 'drive', 'priority': 'high'}, 'priority'),
            ('/api/tasks/start', {'task_name': 'drive', 'on_conflict': 'wait'}, 'on_conflict'),
            ('/api/tasks/start', {'task_name': 'drive', 'timeout_sec': 0}, 'timeout_sec'),
            ('/api/missions', {'subtasks': [{'task_name': 'dock'}], 'priority': 2**31}, 'priority'),
            ('/api/tasks/reprioritize', {'task_ids': ['a']}, 'priority'),
            ('/api/tasks/reprioritize', {'task_ids': [], 'priority': 1}, 'task_ids'),
        ],
    )
    def test_an_unusable_option_is_a_422_naming_the_field_and_starts_nothing(
        self, base: SharedBaseRobot, http: httpx.Client, path: str, body: dict[str, Any], field: str
    ) -> None:
        response = http.post(path, json=body)

        assert response.status_code == 422
        error = check(response.json(), 'error')['error']
        assert (error['code'], error['field']) == ('invalid_request', field)
        assert http.get('/api/active').json() == []

    def test_without_the_token_nothing_is_reprioritized_nor_explained_401(
        self,
        base: SharedBaseRobot,
        http: httpx.Client,
        start_gateway: Callable[..., GatewayProcess],
    ) -> None:
        with httpx.Client(base_url=str(http.base_url)) as stranger:
            responses = [
                stranger.post('/api/tasks/reprioritize', json={'task_ids': ['a'], 'priority': 1}),
                stranger.get('/api/tasks/a/why'),
                stranger.post('/api/tasks/start', json={'task_name': 'drive', 'priority': 100}),
            ]

        assert [r.status_code for r in responses] == [401] * len(responses)
        assert all(check(r.json(), 'error')['error']['code'] == 'unauthorized' for r in responses)
        assert not base.servers['drive'].goals.items

    def test_why_of_an_unknown_task_is_a_404(
        self, base: SharedBaseRobot, http: httpx.Client
    ) -> None:
        for task_id in ('nobody', 'no%00body'):
            response = http.get(f'/api/tasks/{task_id}/why')

            assert response.status_code == 404
            assert check(response.json(), 'error')['error']['code'] == 'unknown_task_id'
