"""Which results the broker has: by the history's sequence numbers, the last acknowledged on disk.

Results go out in sequence order. `sent` is the last handed to the MQTT client; `acked` the
last one the broker acknowledged with every one before it, kept in a file with its task's id
(written with an atomic rename), so that a restart of the bridge sends again what was not
acknowledged and nothing else, and can tell the node's history from a new one that numbers
other tasks from 1 again (a file of one line, from before the task id was kept, is read).
Thread-safe: acknowledgements arrive on the MQTT client's thread.

The file is written once for acknowledgements that come together: `write_soon` asks for
`write_acked()` (the bridge queues it behind its worker's jobs), so a burst of results costs a
write or a few, not one each (a write and a rename: 105 us of CPU and 175 us of wall time here,
which were spent on the MQTT client's thread, under the lock its worker then waited for). An
acknowledgement not yet written when the process dies is sent again after the restart: results
are at least once (QoS 1) anyway.
"""

import contextlib
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path


@dataclass
class _Sent:
    """A result handed to the MQTT client and not yet past `acked`."""

    task_id: str
    acked: bool = False


class ResultOutbox:
    def __init__(self, acked_file: Path, write_soon: Callable[[], None] | None = None) -> None:
        """`write_soon`: asks, from any thread, for `write_acked()` to be called soon (None:
        the file is written at each acknowledgement)."""
        self._file = acked_file
        self._write_soon = write_soon
        self._write_asked = False
        self._lock = threading.Lock()
        self.known = acked_file.exists()
        """Whether a previous run left its acknowledged sequence (else: start from now)."""
        self.acked, self.acked_task_id = _read(acked_file)
        self._written = self.acked, self.acked_task_id
        self.sent = self.acked
        # key: sequence; in the order sent (which is by sequence)
        self._unacked: dict[int, _Sent] = {}
        # key: message id of the MQTT client, value: the sequence it carries
        self._by_message: dict[int, int] = {}
        # acknowledgements that came while a result was being handed over, before its id
        # was known here (publish() had not returned yet)
        self._early_acks: set[int] | None = None

    def is_next(self, sequence: int) -> bool:
        """Whether `sequence` follows what was sent (else a gap to fill from the history)."""
        return sequence == self.sent + 1

    def is_sent(self, sequence: int) -> bool:
        return sequence <= self.sent

    def before_send(self) -> None:
        """Call just before handing a result to the MQTT client (then `mark_sent`)."""
        with self._lock:
            self._early_acks = set()

    def mark_sent(self, sequence: int, message_id: int, task_id: str = '') -> None:
        """`sequence` (of task `task_id`) was handed to the MQTT client as `message_id`."""
        with self._lock:
            early, self._early_acks = self._early_acks or set(), None
            self.sent = max(self.sent, sequence)
            self._unacked[sequence] = _Sent(task_id)
            self._by_message[message_id] = sequence
            if message_id in early:  # acknowledged before publish() returned
                self._acknowledge(message_id)

    def skip(self, sequence: int, task_id: str = '') -> None:
        """`sequence` will never be sent (nothing of it fits in a message): as acknowledged."""
        with self._lock:
            self._early_acks = None
            self.sent = max(self.sent, sequence)
            self._unacked[sequence] = _Sent(task_id, acked=True)
            self._advance()

    def on_ack(self, message_id: int) -> None:
        """The broker acknowledged message `message_id` (on the MQTT client's thread)."""
        with self._lock:
            if message_id in self._by_message:
                self._acknowledge(message_id)
            elif self._early_acks is not None:
                self._early_acks.add(message_id)

    def resend_unacked(self) -> None:
        """After a reconnection: send again everything after the last acknowledged.

        The messages of the connection before keep their ids: the MQTT client sends them
        again too, and their acknowledgements count once sent again here.
        """
        with self._lock:
            self.sent = self.acked
            self._unacked.clear()

    def start_at(self, sequence: int, task_id: str = '') -> None:
        """Treat everything up to `sequence` (of task `task_id`) as acknowledged (a first start:
        from now; 0: the whole history)."""
        with self._lock:
            self.acked = self.sent = sequence
            self.acked_task_id = task_id
            self.known = True
            self._write(sequence, task_id)

    def write_acked(self) -> None:
        """Write the last acknowledged to the file, if it moved since it was last written."""
        with self._lock:
            self._write_asked = False
            if (self.acked, self.acked_task_id) != self._written:
                self._write(self.acked, self.acked_task_id)

    def _acknowledge(self, message_id: int) -> None:
        sequence = self._by_message.pop(message_id)
        sent = self._unacked.get(sequence)
        if sent is None:
            return  # sent before resend_unacked() and not yet again: it will be
        sent.acked = True
        self._advance()

    def _advance(self) -> None:
        """`acked` past every acknowledged sequence at the head of those unacknowledged."""
        advanced, task_id = self.acked, self.acked_task_id
        while self._unacked:
            first, sent = next(iter(self._unacked.items()))
            if not sent.acked:
                break
            del self._unacked[first]
            if first > advanced:
                advanced, task_id = first, sent.task_id
        if advanced == self.acked:
            return
        self.acked, self.acked_task_id = advanced, task_id
        if self._write_soon is None:
            self._write(advanced, task_id)
        elif not self._write_asked:
            self._write_asked = True
            self._write_soon()

    def _write(self, sequence: int, task_id: str) -> None:
        _write(self._file, sequence, task_id)
        self._written = sequence, task_id


def _read(path: Path) -> tuple[int, str]:
    """The last acknowledged sequence and its task's id ('' if the file does not say)."""
    with contextlib.suppress(OSError, ValueError):
        sequence, _, rest = path.read_text().partition('\n')
        return max(int(sequence.strip() or 0), 0), rest.partition('\n')[0]
    return 0, ''


def _write(path: Path, sequence: int, task_id: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f'{path.name}.partial')
    partial.write_text(f'{sequence}\n{task_id}\n')
    os.replace(partial, path)
