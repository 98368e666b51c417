"""GET /metrics (issue 30, item 4): Prometheus' text format, read with prometheus_client's own
parser, against a real gateway process and a real Task Manager whose drive and dock share
`base` (so that a dock waits in the queue)."""

from collections.abc import Callable, Iterator

import httpx
import pytest
from prometheus_client.parser import text_string_to_metric_families
from prometheus_client.samples import Sample

from task_manager.testing.gateway import TIMEOUT_SEC, SharedBaseRobot, check, wait_until
from task_manager_web.testing import GatewayProcess, gateway_client

pytestmark = pytest.mark.ros

# key: (sample name, its labels as sorted pairs), value: the sample's value
Samples = dict[tuple[str, tuple[tuple[str, str], ...]], float]


@pytest.fixture
def http(base: SharedBaseRobot, gateway: GatewayProcess) -> Iterator[httpx.Client]:
    with gateway_client(gateway) as client:
        yield client


def scrape(http: httpx.Client) -> Samples:
    """GET /metrics, parsed by prometheus_client's parser: every sample by name and labels."""
    response = http.get('/metrics')
    assert response.status_code == 200, response.text
    assert response.headers['content-type'].startswith('text/plain; version=')
    samples: list[Sample] = [
        sample
        for family in text_string_to_metric_families(response.text)
        for sample in family.samples
    ]
    return {(s.name, tuple(sorted(s.labels.items()))): s.value for s in samples}


def labels(**values: str) -> tuple[tuple[str, str], ...]:
    return tuple(sorted(values.items()))


def start(http: httpx.Client, task_name: str, task_id: str, **options: str) -> None:
    body = {'task_name': task_name, 'task_data': {'order': 1}, 'task_id': task_id, **options}
    response = http.post('/api/tasks/start', json=body)
    assert response.status_code == 202, response.text


def test_metrics_count_the_tasks_ended_the_active_and_queued_ones_and_the_requests(
    base: SharedBaseRobot, http: httpx.Client
) -> None:
    nightly = {
        'schedule_id': 'nightly',
        'task_name': 'dock',
        'task_data': '{"order": 1}',
        'cron': '0 2 * * *',
    }
    scheduled = http.post(
        '/api/tasks/start',
        json={'task_name': 'system/schedule', 'task_data': nightly},
        params={'wait': 'true'},
    )
    drive = base.servers['drive']
    start(http, 'drive', 'drive-ok')
    drive.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    start(http, 'drive', 'drive-bad')
    drive.wait_for_goals(2, TIMEOUT_SEC)[1].abort()
    start(http, 'drive', 'drive-on')
    running = drive.wait_for_goals(3, TIMEOUT_SEC)[2]
    start(http, 'dock', 'dock-waits', on_conflict='queue')
    base.probe.wait_active(
        lambda t: ('dock-waits', 'QUEUED') in t and ('drive-on', 'IN_PROGRESS') in t
    )
    ended = [
        check(http.get(f'/api/tasks/{task_id}').json(), 'task')['status']
        for task_id in ('drive-ok', 'drive-bad')
    ]

    def both_counted() -> Samples | None:
        samples = scrape(http)
        errors = samples.get(
            ('task_manager_tasks_ended_total', labels(task_name='drive', status='ERROR'))
        )
        return samples if errors == 1 else None

    samples = wait_until(both_counted, 'the ERROR end counted')

    assert ended == ['DONE', 'ERROR']
    done_key = ('task_manager_tasks_ended_total', labels(task_name='drive', status='DONE'))
    assert samples[done_key] == 1
    assert not any(
        name == 'task_manager_tasks_ended_total' and dict(key)['task_name'] == 'dock'
        for name, key in samples
    )
    assert samples[('task_manager_task_duration_seconds_count', labels(task_name='drive'))] == 2
    assert samples[('task_manager_task_duration_seconds_sum', labels(task_name='drive'))] >= 0
    assert samples[('task_manager_active_tasks', ())] == 2
    assert samples[('task_manager_queued_tasks', ())] == 1
    assert samples[('task_manager_paused_tasks', ())] == 0
    assert samples[('task_manager_web_connected', ())] == 1
    start_requests = (
        'task_manager_web_requests_total',
        labels(route='/api/tasks/start', method='POST', status='202'),
    )
    assert samples[start_requests] == 4
    task_reads = (
        'task_manager_web_requests_total',
        labels(route='/api/tasks/{task_id:path}', method='GET', status='200'),
    )
    assert samples[task_reads] == 2
    start_timings = (
        'task_manager_web_request_duration_seconds_count',
        labels(route='/api/tasks/start', method='POST'),
    )
    assert samples[start_timings] == 5  # the four starts and the schedule's (200)
    assert check(scheduled.json(), 'started')['task']['status'] == 'DONE', scheduled.text
    nightly_labels = labels(schedule_id='nightly', task_name='dock')
    assert samples[('task_manager_schedule_runs_total', nightly_labels)] == 0
    assert samples[('task_manager_schedule_misses_total', nightly_labels)] == 0

    running.succeed()
    base.servers['dock'].wait_for_goals(1, TIMEOUT_SEC)[0].succeed()
    base.probe.wait_active(lambda t: not t)
    after = wait_until(
        lambda: (s := scrape(http))[('task_manager_active_tasks', ())] == 0 and s,
        'no active task counted',
    )
    assert after[('task_manager_tasks_ended_total', labels(task_name='dock', status='DONE'))] == 1
    assert after[('task_manager_queued_tasks', ())] == 0
    # the scrapes before this one (a request is counted once its answer's head is sent)
    scrapes = (
        'task_manager_web_requests_total',
        labels(route='/metrics', method='GET', status='200'),
    )
    assert after[scrapes] >= 1


def test_metrics_need_the_token_even_when_reading_does_not(
    start_gateway: Callable[..., GatewayProcess],
) -> None:
    gateway = start_gateway('--read-without-token')
    with httpx.Client(base_url=gateway.url, timeout=TIMEOUT_SEC) as anyone:
        refused = anyone.get('/metrics')
        wrong = anyone.get('/metrics', headers={'Authorization': 'Bearer not-the-token'})
        allowed = anyone.get('/metrics', headers={'Authorization': f'Bearer {gateway.token}'})

    for response in (refused, wrong):
        assert response.status_code == 401
        assert check(response.json(), 'error')['error']['code'] == 'unauthorized'
        assert response.headers['www-authenticate'].startswith('Bearer')
    assert allowed.status_code == 200
    # no Task Manager in reach: the gateway says so, and no count of the node's is made up
    names = {f.name for f in text_string_to_metric_families(allowed.text)}
    assert 'task_manager_web_connected' in names
    assert 'task_manager_active_tasks' not in names


def test_metrics_without_token_lets_a_scraper_read_them_and_nothing_else(
    start_gateway: Callable[..., GatewayProcess],
) -> None:
    gateway = start_gateway('--metrics-without-token')
    with httpx.Client(base_url=gateway.url, timeout=TIMEOUT_SEC) as scraper:
        metrics = scraper.get('/metrics')
        active = scraper.get('/api/active')

    assert metrics.status_code == 200
    families = {f.name: f for f in text_string_to_metric_families(metrics.text)}
    assert families['task_manager_web_connected'].samples[0].value == 0
    assert active.status_code == 401
