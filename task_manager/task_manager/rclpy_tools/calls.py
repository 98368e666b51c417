"""Service requests sent and answered at a cost that does not grow with the requests in flight.

rclpy's `Client.call_async` (9.1.2) makes its future through a generic alias
(`Future[SrvResponseT]()`, a typing lookup per call) and registers `remove_pending_request` as
its done callback, which finds the future by walking every pending request: with 500 requests
in flight, each answer walked 500. rclpy's executor also runs each done callback of an answered
future as a task of its own (its `_take_client` gives the future the executor).

`call_async` here sends the same request and keeps its future, which knows the request's
number, in the client's own table of pending requests, as rclpy does, so that an executor's
take of the response finds it; its done callback, and `forget` for a caller that waits no more,
remove it by that number. `take_pending` takes an answered request's future out of that table
by its number, for an executor that completes it in place (the ParkingExecutor): the future's
done callbacks then run at once, in the handler of the response.
"""

from functools import partial
from typing import Any

from rclpy.client import Client
from rclpy.task import Future


class Call(Future[Any]):
    """The future of a request sent by `call_async`: its number in its client's table."""

    def __init__(self, number: int) -> None:
        super().__init__()
        self.number = number


def call_async(client: Client[Any, Any], request: Any) -> Future[Any]:
    """Send `request`; a future of its response (Client.call_async's, see the module)."""
    if not isinstance(request, client.srv_type.Request):
        raise TypeError(f'{type(request).__name__} is not a request of {client.srv_type.__name__}')
    with client._lock:
        with client.handle:
            number = client.handle.send_request(request)
        if number in client._pending_requests:
            raise RuntimeError(f'Sequence ({number}) conflicts with pending request')
        future = client._pending_requests[number] = Call(number)
    future.add_done_callback(partial(_forget, client))
    return future


def forget(client: Client[Any, Any], future: Future[Any]) -> None:
    """The caller waits no more for `future`'s response: out of the client's table (by its
    number for a request of `call_async`, else by rclpy's walk of every pending request); the
    future stays as it is."""
    if isinstance(future, Call):
        _forget(client, future)
    else:
        client.remove_pending_request(future)


def take_pending(client: Client[Any, Any], number: int) -> Future[Any] | None:
    """The future of the pending request `number`, out of the client's table; None when there
    is none (cancelled, forgotten, or never sent by this client)."""
    with client._lock:
        return client._pending_requests.pop(number, None)


def _forget(client: Client[Any, Any], future: Call) -> None:
    """`future`'s request is pending no more (answered, cancelled or forgotten)."""
    with client._lock:
        if client._pending_requests.get(future.number) is future:
            del client._pending_requests[future.number]
