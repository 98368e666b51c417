"""The FleetClient's MQTT transport: paho's client driven by a thread of its own, on a socket
that reads in large chunks and writes in one go.

paho's own thread (loop_start) reads a packet in three system calls or more (its type, its
length, its body) and looks at the socket again (select) before each packet; every packet it
queues to write, an acknowledgement among them, wakes that thread through a socket pair (one
more call), and each is written with a call of its own. At thousands of messages a second
those calls were most of a console's time. Here one read takes up to READ_CHUNK_BYTES, every
packet that came with it is handled before the socket is looked at again, and what was queued
meanwhile (acknowledgements, requests) goes out in one call; a packet queued from another
thread wakes the loop once, not once per packet.

It drives paho through its public external-loop calls (reconnect, loop_read, loop_write,
loop_misc, want_write and the socket_register_write callbacks), reconnecting as loop_forever
does. paho is pinned (pyproject.toml): `BufferedClient` wraps the socket paho makes in
`_create_socket`, its one hook into paho's internals.
"""

import contextlib
import logging
import select
import socket
import ssl
import struct
import threading
from collections.abc import Callable
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import MQTTErrorCode

LOG = logging.getLogger('task_manager_mqtt.fleet')
READ_CHUNK_BYTES = 256 * 1024
"""The most one read takes from the socket."""
WRITE_HELD_MAX_BYTES = 4 * 1024 * 1024
"""Bytes kept to write, at most; beyond them paho keeps its packets queued until there is room."""
PACKETS_PER_ROUND = 1000
"""Packets handled from what was read before the loop writes and looks at the socket again."""
HOUSEKEEPING_SEC = 1.0
"""The longest the loop waits without looking after the keep-alive."""
NOT_NOW = (BlockingIOError, ssl.SSLWantReadError, ssl.SSLWantWriteError)
Received = Callable[[str, bytes, int, int], None]
"""received(topic, payload, mid, qos)."""


class BufferedSocket:
    """A connected socket (or TLS socket) that reads ahead and writes when flushed; anything
    else is the socket's own. Used by its loop's thread only."""

    def __init__(self, sock: Any) -> None:
        self.sock = sock
        self._read = bytearray()
        self._write = bytearray()

    def recv(self, size: int) -> bytes:
        """Up to `size` bytes: from what was read ahead, else from one read of up to
        READ_CHUNK_BYTES (BlockingIOError when nothing has come; b'' at the end)."""
        if not self._read:
            data = self.sock.recv(max(size, READ_CHUNK_BYTES))
            if len(data) <= size:
                return bytes(data)
            self._read += data
        chunk = bytes(self._read[:size])
        del self._read[:size]
        return chunk

    def pending(self) -> int:
        """Bytes there to read at once: read ahead, and those a TLS socket holds decrypted."""
        inner = self.sock.pending() if hasattr(self.sock, 'pending') else 0
        return len(self._read) + inner

    def send(self, data: bytes | bytearray) -> int:
        """Keep `data` to write at the next flush: all of it, or BlockingIOError while
        WRITE_HELD_MAX_BYTES wait and the socket takes none of them."""
        if len(self._write) >= WRITE_HELD_MAX_BYTES:
            self.flush()
            if len(self._write) >= WRITE_HELD_MAX_BYTES:
                raise BlockingIOError('the socket takes no more for now')
        self._write += data
        return len(data)

    @property
    def holds_writes(self) -> bool:
        return bool(self._write)

    def flush(self) -> None:
        """Write what is kept, as much as the socket takes now. A connection that fails is shut
        down: paho finds it lost at its next read, and it is connected again as usual."""
        while self._write:
            try:
                written = self.sock.send(self._write)
            except NOT_NOW:
                return
            except OSError:
                self._write.clear()
                with contextlib.suppress(OSError):
                    self.sock.shutdown(socket.SHUT_RDWR)
                return
            del self._write[:written]

    def close(self) -> None:
        """Write what is kept (a DISCONNECT, say) if the socket takes it now, then close."""
        self.flush()
        self.sock.close()

    def __getattr__(self, name: str) -> Any:
        return getattr(self.sock, name)


class BufferedClient(mqtt.Client):
    """paho's client on a BufferedSocket; driven by a ClientLoop (which writes what the socket
    keeps), never by paho's own loop.

    With `on_received` set, each message of QoS 0 or 1 is handed to it as its topic, payload,
    message id and QoS, read straight from the packet: paho makes an MQTTMessage (with a lock
    of its own) and reads every MQTT 5 property of each, and that was a third of a console's
    time. With manual_ack the callback acknowledges; else paho does, as usual. A message of
    QoS 2, or one whose topic does not read, goes paho's way (to on_message).
    """

    on_received: Received | None = None

    def _create_socket(self) -> Any:
        return BufferedSocket(super()._create_socket())

    def _handle_publish(self) -> MQTTErrorCode:
        received = self.on_received
        command = self._in_packet['command']
        qos = (command & 0x06) >> 1
        if received is None or qos == 2:
            return super()._handle_publish()
        try:
            topic, payload, mid = publish_parts(self._in_packet['packet'], qos)
        except (ValueError, struct.error):  # paho says what is wrong with it
            return super()._handle_publish()
        try:
            received(topic, payload, mid, qos)
        except Exception:  # the callback's boundary, as paho's around on_message
            LOG.exception('a message on %s was not handled', topic)
        if qos == 1 and not self._manual_ack:
            return self._send_puback(mid)
        return mqtt.MQTT_ERR_SUCCESS


def publish_parts(packet: bytes | bytearray, qos: int) -> tuple[str, bytes, int]:
    """The topic, payload and message id of an MQTT 5 PUBLISH packet's variable header and
    payload (its properties skipped); ValueError if it does not read (a topic alias among)."""
    (length,) = struct.unpack_from('!H', packet, 0)
    end = 2 + length
    if not length or end > len(packet):
        raise ValueError('no topic name')
    topic = bytes(packet[2:end]).decode()  # UnicodeDecodeError is a ValueError
    mid = 0
    if qos:
        (mid,) = struct.unpack_from('!H', packet, end)
        end += 2
    properties, shift = 0, 0
    while True:  # a Variable Byte Integer: 7 bits a byte, at most 4 bytes
        if end >= len(packet) or shift > 21:
            raise ValueError('bad properties length')
        byte = packet[end]
        end += 1
        properties |= (byte & 0x7F) << shift
        shift += 7
        if not byte & 0x80:
            break
    end += properties
    if end > len(packet):
        raise ValueError('properties past the end')
    return topic, bytes(packet[end:]), mid


class ClientLoop:
    """The thread that drives one client (a BufferedClient), in place of paho's loop_start:
    connects (and connects again after a loss, waiting `reconnect_min_sec`, doubling up to
    `reconnect_max_sec`), reads, writes and keeps the connection alive."""

    def __init__(
        self, client: mqtt.Client, reconnect_min_sec: float, reconnect_max_sec: float
    ) -> None:
        self.client = client
        self._reconnect_sec = (reconnect_min_sec, reconnect_max_sec)
        self._wake_read, self._wake_write = socket.socketpair()
        for end in (self._wake_read, self._wake_write):
            end.setblocking(False)
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name='fleet-mqtt', daemon=True)
        client.on_socket_register_write = lambda *_: self._wake_from_elsewhere()
        client.on_socket_unregister_write = lambda *_: self._queued_meanwhile()

    def start(self) -> None:
        """Drive the client, after its `connect_async`."""
        self._thread.start()

    def stop(self, timeout_sec: float) -> None:
        """Disconnect (what is queued is written first) and end the thread."""
        self._stopping.set()
        self._wake()
        if self._thread.is_alive():
            self._thread.join(timeout_sec)
        self._wake_read.close()
        self._wake_write.close()

    def _wake(self) -> None:
        with contextlib.suppress(BlockingIOError, OSError):  # full: a wake-up is pending
            self._wake_write.send(b'\0')

    def _wake_from_elsewhere(self) -> None:
        """paho queued a packet: another thread's must wake the loop (its own writes anyway)."""
        if threading.current_thread() is not self._thread:
            self._wake()

    def _queued_meanwhile(self) -> None:
        """paho found nothing to write: a packet queued by another thread since it looked had
        no wake-up (paho thought the loop was to write anyway), so look again."""
        if self.client.want_write():
            self._wake_from_elsewhere()

    def _run(self) -> None:
        delay = 0.0
        while not self._stopping.is_set():
            sock = self.client.socket()
            if isinstance(sock, BufferedSocket):
                try:
                    self._round(sock)
                except Exception:  # a bug, ours or paho's: the thread goes on, connected again
                    LOG.exception('the MQTT connection failed; connecting again')
                    with contextlib.suppress(OSError):  # paho finds it lost at its next read
                        sock.shutdown(socket.SHUT_RDWR)
                    self._stopping.wait(self._reconnect_sec[0])
                if self.client.is_connected():
                    delay = 0.0
                continue
            if delay:
                self._stopping.wait(delay)
            delay = min(max(delay * 2, self._reconnect_sec[0]), self._reconnect_sec[1])
            if not self._stopping.is_set():
                self._connect()
        if isinstance(self.client.socket(), BufferedSocket):  # what is queued, then DISCONNECT
            self.client.disconnect()
            self.client.loop_write()  # the socket is closed once DISCONNECT is written

    def _connect(self) -> None:
        try:
            self.client.reconnect()
        except (OSError, ssl.SSLError) as error:  # tried again, as loop_forever does
            LOG.debug('no connection to the broker: %s', error)

    def _round(self, sock: BufferedSocket) -> None:
        """Wait for the socket, then read all that came, write all that is queued, and look
        after the keep-alive."""
        wanted = sock.holds_writes or self.client.want_write()
        timeout = 0.0 if sock.pending() else HOUSEKEEPING_SEC
        watched: list[Any] = [sock, self._wake_read]
        try:
            readable, _, _ = select.select(watched, watched[:1] if wanted else [], [], timeout)
        except (OSError, ValueError):  # closed meanwhile: paho finds it lost as it reads
            readable = [sock]
        if self._wake_read in readable:
            with contextlib.suppress(BlockingIOError):
                self._wake_read.recv(4096)
        if sock in readable or sock.pending():
            for _ in range(PACKETS_PER_ROUND):
                if self.client.loop_read() != mqtt.MQTT_ERR_SUCCESS or not sock.pending():
                    break
        if self.client.socket() is not sock:  # lost while reading
            return
        if self.client.want_write():
            self.client.loop_write()
        sock.flush()
        self.client.loop_misc()
