"""The gateway's live event stream (Server-Sent Events) over a real node, and the node's comings
and goings as the stream reports them."""

import contextlib
import json
import re
import time
from collections.abc import Callable, Iterator
from typing import Any

import httpx
import pytest

from task_manager.testing.gateway import TIMEOUT_SEC, Robot, check, wait_until
from task_manager.testing.harness import RosHarness
from task_manager.testing.lost_events import batch_writer, event_batch, flood_while_stopped
from task_manager_web.testing import GatewayProcess

pytestmark = pytest.mark.ros
STREAM_TIMEOUT_SEC = 2 * TIMEOUT_SEC


class Stream:
    """One open /api/events stream, read event by event."""

    def __init__(self, response: httpx.Response) -> None:
        assert response.status_code == 200, response.read()
        assert response.headers['content-type'].startswith('text/event-stream')
        self._lines = response.iter_lines()

    def next(self) -> tuple[str, Any]:
        """The next event: (its kind, its data); AssertionError if none comes within
        STREAM_TIMEOUT_SEC (keepalive comments come meanwhile, each 15 s)."""
        deadline = time.monotonic() + STREAM_TIMEOUT_SEC
        kind, data = '', ''
        for line in self._lines:
            if time.monotonic() > deadline:
                raise AssertionError(f'no event within {STREAM_TIMEOUT_SEC} s')
            if line.startswith('event: '):
                kind = line[len('event: ') :]
            elif line.startswith('data: '):
                data += line[len('data: ') :]
            elif not line and kind:
                return kind, json.loads(data)
        raise AssertionError('the stream ended')

    def until(self, wanted: Callable[[str, Any], bool]) -> list[tuple[str, Any]]:
        """Events up to and with the first `wanted` one."""
        seen = [self.next()]
        while not wanted(*seen[-1]):
            seen.append(self.next())
        return seen


def open_stream(client: httpx.Client, **params: str) -> Iterator[Stream]:
    with client.stream('GET', '/api/events', params=params) as response:
        yield Stream(response)


@pytest.fixture
def events(http: httpx.Client) -> Iterator[Stream]:
    yield from open_stream(http)


def ended(task_id: str) -> Callable[[str, Any], bool]:
    return lambda kind, data: (
        kind == 'task' and data['event'] == 'ENDED' and (data['task']['task_id'] == task_id)
    )


def test_every_event_of_a_task_arrives_in_order_as_json(
    robot: Robot, http: httpx.Client, events: Stream
) -> None:
    assert events.next() == ('hello', {'connected': True})
    body = {'task_name': 'fib', 'task_data': {'order': 5}, 'task_id': 'e1'}
    assert http.post('/api/tasks/start', json=body).status_code == 202
    robot.fib.wait_for_goals(1, TIMEOUT_SEC)[0].succeed()

    seen = events.until(ended('e1'))

    mine = [check(data, 'task_event') for kind, data in seen if data['task']['task_id'] == 'e1']
    assert [e['event'] for e in mine] == ['RECEIVED', 'STARTED', 'ENDED']
    assert [e['task']['status'] for e in mine] == ['RECEIVED', 'IN_PROGRESS', 'DONE']
    assert mine[-1]['task']['source'] == 'WEB' and mine[-1]['task']['sequence'] > 0


def test_many_streams_each_get_every_event(
    robot: Robot, http: httpx.Client, gateway: GatewayProcess
) -> None:
    with contextlib.ExitStack() as open_streams:
        readers = []
        for _ in range(20):
            client = open_streams.enter_context(
                httpx.Client(base_url=gateway.url, timeout=TIMEOUT_SEC)
            )
            # `?token=`: as a browser's EventSource sends it
            response = open_streams.enter_context(
                client.stream('GET', '/api/events', params={'token': gateway.token})
            )
            readers.append(Stream(response))
        assert all(r.next()[0] == 'hello' for r in readers)
        assert http.get('/api/health').json()['event_streams'] == len(readers)

        for index in range(5):
            body = {'task_name': 'instant', 'task_data': {'data': True}, 'task_id': f'many-{index}'}
            http.post('/api/tasks/start', params={'wait': 'true'}, json=body)
        for reader in readers:
            seen = reader.until(ended('many-4'))
            ends = [d['task']['task_id'] for _, d in seen if d.get('event') == 'ENDED']
            assert ends == [f'many-{i}' for i in range(5)]

    wait_until(lambda: http.get('/api/health').json()['event_streams'] == 0, 'streams closed')


def _next_change(stream: Any, connected: bool) -> Any:
    """The next event but a `connection` that says `connected` again (as when the node's events
    reach the gateway a moment after the node did: the page then reads its tasks again)."""
    while (event := stream.next()) == ('connection', {'connected': connected}):
        pass
    return event


def test_the_stream_says_when_the_node_goes_and_comes_back(
    start_robot: Callable[[], Robot], start_gateway: Callable[..., GatewayProcess]
) -> None:
    gateway = start_gateway()
    headers = {'Authorization': f'Bearer {gateway.token}'}
    with httpx.Client(base_url=gateway.url, headers=headers, timeout=TIMEOUT_SEC) as client:
        for stream in open_stream(client):
            assert stream.next() == ('hello', {'connected': False})

            robot = start_robot()
            assert stream.next() == ('connection', {'connected': True})
            assert client.get('/api/active').status_code == 200

            robot.process.stop()
            assert _next_change(stream, True) == ('connection', {'connected': False})
            assert client.get('/api/active').status_code == 503

            start_robot()
            assert stream.next() == ('connection', {'connected': True})


def test_the_stream_ends_with_bye_when_the_gateway_stops(
    robot: Robot, gateway: GatewayProcess, events: Stream
) -> None:
    """An open stream does not hold the stop: it is ended, and says why (a page then
    reconnects to the gateway started next)."""
    assert events.next() == ('hello', {'connected': True})

    assert gateway.stop() == 0

    assert events.next() == ('bye', {'message': 'the gateway stops'})


def test_a_stream_ends_with_overflow_when_the_gateway_lost_events(
    ros: RosHarness, robot: Robot, gateway: GatewayProcess, events: Stream
) -> None:
    """The gateway stopped (SIGSTOP) while more batches of task events came than it keeps: when
    it goes on, an open stream ends with `overflow` saying how many went missing, after the
    events before the gap (the page then opens the stream again and reads the tasks as they
    are). The batches come from the test, standing in for the node's writer."""
    assert events.next() == ('hello', {'connected': True})
    writer = batch_writer(ros)
    writer.publish(event_batch('first'))
    assert events.next()[1]['task']['task_id'] == 'first'  # the gateway took one of its batches

    flood_while_stopped(writer, gateway.process.pid)

    seen = events.until(lambda kind, _: kind == 'overflow')
    missing = seen[-1][1]['message']
    assert re.fullmatch(
        r'\d+ batch\(es\) of task events went missing \(the gateway fell behind the Task '
        r'Manager\): reconnect',
        missing,
    ), missing
    flooded = [data['task']['task_id'] for kind, data in seen if kind == 'task']
    numbers = [int(task_id[1:]) for task_id in flooded if task_id != 'after']
    assert numbers == sorted(numbers), numbers
