"""`RobotLoop`: one thread that drives the MQTT connections of many simulated robots (paho's
external loop over a selector): every call of their clients runs on it, and timers too.

Their clients (RobotClient) are the FleetClient's BufferedClient, and publish at QoS 1 by
writing their PUBLISH packets themselves (`publish_qos1`): paho's publish keeps a message, a
lock and its properties for each, which cost a simulated robot more than the console spends on
the message. paho still makes the connection (CONNECT, the last will), keeps it alive and reads
the broker's acknowledgements, which go to `on_acknowledged`. What a robot publishes in one round
of the loop goes out in one write; a lost connection is not made again (nor its messages sent
again)."""

import contextlib
import heapq
import itertools
import logging
import queue
import selectors
import socket
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any, TypeVar

import paho.mqtt.client as mqtt
from paho.mqtt.enums import MQTTErrorCode
from task_manager_mqtt.fleet.transport import PACKETS_PER_ROUND, BufferedClient, BufferedSocket

LOG = logging.getLogger('task_manager_console.simulation')
TIMEOUT_SEC = 20.0
"""How long a call waits for the loop's thread (and the tests for what robots send)."""
HOUSEKEEPING_SEC = 1.0
"""How often each connection's keep-alive is looked after (paho's loop_misc)."""
T = TypeVar('T')
PUBLISH_QOS1 = 0x32
"""A PUBLISH packet's first byte at QoS 1 (| 1: retained)."""
FAILURE = 0x80
"""The smallest reason code that is a failure."""


class RobotClient(BufferedClient):
    """A BufferedClient that publishes at QoS 1 by writing its packets itself; every PUBACK
    is handed to `on_acknowledged(mid, reason_code)` (paho keeps no message of them; a code of
    FAILURE or more is a refusal). Used on its RobotLoop's thread only."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.on_acknowledged: Callable[[int, int], None] = lambda _, __: None
        self._next_mid = 0

    def publish_qos1(self, topic: str, payload: bytes, retain: bool = False) -> int:
        """Queue a PUBLISH of QoS 1 (written with the loop's next round); its message id.
        RuntimeError if the robot is not connected."""
        sock = self.socket()
        if not isinstance(sock, BufferedSocket):
            raise RuntimeError('not connected to the broker')
        self._next_mid = self._next_mid % 65535 + 1
        name = topic.encode()
        body = b'%s%s%s\x00%s' % (
            len(name).to_bytes(2, 'big'),
            name,
            self._next_mid.to_bytes(2, 'big'),
            payload,
        )
        sock.send(bytes([PUBLISH_QOS1 | retain]) + _remaining_length(len(body)) + body)
        return self._next_mid

    def _handle_pubackcomp(self, cmd: Any) -> MQTTErrorCode:
        packet = self._in_packet['packet']
        if cmd != 'PUBACK' or len(packet) < 2:
            return super()._handle_pubackcomp(cmd)
        mid = int.from_bytes(packet[:2], 'big')
        self.on_acknowledged(mid, packet[2] if len(packet) > 2 else 0)
        return mqtt.MQTT_ERR_SUCCESS


def _remaining_length(length: int) -> bytes:
    """MQTT's Variable Byte Integer of a packet's remaining length."""
    encoded = bytearray()
    while True:
        length, byte = length >> 7, length & 0x7F
        encoded.append(byte | (0x80 if length else 0))
        if not length:
            return bytes(encoded)


class RobotLoop:
    """One thread that drives the MQTT connections of many robots: every call of their paho
    clients runs on it (`run`), and timers (`every`) too."""

    _shared: 'RobotLoop | None' = None
    _shared_lock = threading.Lock()

    @classmethod
    def shared(cls) -> 'RobotLoop':
        """The process's loop, started at its first use (it lives as long as the process)."""
        with cls._shared_lock:
            if cls._shared is None:
                cls._shared = cls()
            return cls._shared

    def __init__(self) -> None:
        self._selector = selectors.DefaultSelector()
        self._wake_read, self._wake_write = socket.socketpair()
        for end in (self._wake_read, self._wake_write):
            end.setblocking(False)
        self._selector.register(self._wake_read, selectors.EVENT_READ, None)
        self._calls: queue.SimpleQueue[tuple[Callable[[], Any], Future[Any]]] = queue.SimpleQueue()
        # key: a client attached, value: its socket and the events watched on it
        self._clients: dict[mqtt.Client, tuple[Any, int]] = {}
        self._touched: set[mqtt.Client] = set()
        """Clients that may have something to write since the loop last looked."""
        # (due, order, period, function): a timer; its function returns False to end it
        self._timers: list[tuple[float, int, float, Callable[[], bool]]] = []
        self._order = itertools.count()
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name='simulated-robots', daemon=True)
        self._thread.start()

    def run(self, function: Callable[[], T], timeout_sec: float = TIMEOUT_SEC) -> T:
        """`function()` on the loop's thread (at once when called from it); its value."""
        if threading.current_thread() is self._thread:
            return function()
        done: Future[T] = Future()
        self._calls.put((function, done))
        with contextlib.suppress(BlockingIOError):  # full: a wake-up is pending anyway
            self._wake_write.send(b'\0')
        return done.result(timeout_sec)

    def every(self, period_sec: float, function: Callable[[], bool]) -> None:
        """Call `function()` on the loop's thread every `period_sec` until it returns False."""

        def add() -> None:
            due = time.monotonic() + period_sec
            heapq.heappush(self._timers, (due, next(self._order), period_sec, function))

        self.run(add)

    def attach(self, client: mqtt.Client) -> None:
        """Drive `client`, just connected (on the loop's thread)."""
        sock = client.socket()
        assert sock is not None, 'attach a client once it is connected'
        self._selector.register(sock, selectors.EVENT_READ, client)
        self._clients[client] = (sock, selectors.EVENT_READ)
        self._touched.add(client)

    def detach(self, client: mqtt.Client) -> None:
        """Drive `client` no more (on the loop's thread); before its socket is closed."""
        attached = self._clients.pop(client, None)
        if attached is not None:
            self._selector.unregister(attached[0])

    def touch(self, client: mqtt.Client) -> None:
        """`client` has queued something to write (on the loop's thread)."""
        self._touched.add(client)

    def close(self) -> None:
        """End the thread (its robots closed first); the shared loop is never closed."""

        def stop() -> None:
            self._stopping = True

        self.run(stop)
        self._thread.join(TIMEOUT_SEC)
        self._selector.close()
        self._wake_read.close()
        self._wake_write.close()

    def _run(self) -> None:
        housekeeping = time.monotonic() + HOUSEKEEPING_SEC
        while not self._stopping:
            due = self._timers[0][0] if self._timers else housekeeping
            timeout = max(min(due, housekeeping) - time.monotonic(), 0.0)
            for key, events in self._selector.select(timeout):
                if key.data is None:
                    self._run_calls()
                else:
                    self._serve(key.data, events)
            self._run_timers()
            if time.monotonic() >= housekeeping:
                housekeeping = time.monotonic() + HOUSEKEEPING_SEC
                for client in list(self._clients):
                    self._guarded(client, client.loop_misc)
            self._flush()

    def _serve(self, client: mqtt.Client, events: int) -> None:
        if client not in self._clients:  # detached by an earlier event of this round
            return
        if events & selectors.EVENT_READ:
            self._guarded(client, lambda: self._read_all(client))
        self._touched.add(client)

    @staticmethod
    def _read_all(client: mqtt.Client) -> Any:
        """loop_read until what one read took is handled (its last code)."""
        code = client.loop_read()
        for _ in range(PACKETS_PER_ROUND):
            sock = client.socket()
            if code != mqtt.MQTT_ERR_SUCCESS or not isinstance(sock, BufferedSocket):
                break
            if not sock.pending():
                break
            code = client.loop_read()
        return code

    def _run_calls(self) -> None:
        with contextlib.suppress(BlockingIOError):
            self._wake_read.recv(4096)
        while True:
            try:
                function, done = self._calls.get_nowait()
            except queue.Empty:
                return
            try:
                done.set_result(function())
            except Exception as error:  # the caller's: handed back to it
                done.set_exception(error)

    def _run_timers(self) -> None:
        now = time.monotonic()
        while self._timers and self._timers[0][0] <= now:
            due, _, period_sec, function = heapq.heappop(self._timers)
            try:
                again = function()
            except Exception:  # a timer's bug: logged, the timer ends, the loop goes on
                LOG.exception('a timer of the simulated robots failed')
                continue
            if again:
                heapq.heappush(self._timers, (due + period_sec, next(self._order), period_sec,
                                              function))  # fmt: skip

    def _flush(self) -> None:
        """Write what the clients touched have queued; watch for room where a write waits."""
        touched, self._touched = self._touched, set()
        for client in touched:
            if client not in self._clients:
                continue
            if client.want_write():
                self._guarded(client, client.loop_write)
            attached = self._clients.get(client)
            if attached is None:
                continue
            sock, watched = attached
            if isinstance(sock, BufferedSocket):
                sock.flush()
            waiting = client.want_write() or (
                isinstance(sock, BufferedSocket) and sock.holds_writes
            )
            wanted = selectors.EVENT_READ | (selectors.EVENT_WRITE if waiting else 0)
            if wanted != watched:
                self._selector.modify(sock, wanted, client)
                self._clients[client] = (sock, wanted)

    def _guarded(self, client: mqtt.Client, step: Callable[[], Any]) -> None:
        """One step of paho's loop; a connection it finds lost is detached (never retried)."""
        try:
            code = step()
        except Exception:  # a bug in a callback: logged, the other robots go on
            LOG.exception('a simulated robot failed')
            code = None
        if code in (mqtt.MQTT_ERR_CONN_LOST, mqtt.MQTT_ERR_NO_CONN) or client.socket() is None:
            self.detach(client)
