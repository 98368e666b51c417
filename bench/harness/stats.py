"""Medians, 95th percentiles, ratios and the measuring loops every benchmark shares."""

import math
import statistics
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from rclpy.task import Future

from bench.harness import config
from bench.harness.replies import BenchError, Reply, wait_reply


@dataclass(frozen=True)
class Summary:
    """Median and 95th percentile (nearest rank) of a set of samples."""

    median: float
    p95: float
    count: int

    @classmethod
    def of(cls, samples: Sequence[float]) -> 'Summary':
        if not samples:
            raise BenchError('no samples')
        ordered = sorted(samples)
        rank = max(math.ceil(0.95 * len(ordered)) - 1, 0)
        return cls(statistics.median(ordered), ordered[rank], len(ordered))

    def text(self, digits: int = 2) -> str:
        return f'{self.median:.{digits}f} / {self.p95:.{digits}f}'


def ratio(measured: float, baseline: float) -> float:
    return measured / baseline if baseline > 0 else math.inf


def latency_ms(
    send: Callable[[], Future[Any]],
    check: Callable[[Reply], None],
    what: str,
    timeout_sec: float = config.SAMPLE_TIMEOUT_SEC,
) -> float:
    """Time one request from send to reply, in ms; `check` raises BenchError on a bad reply."""
    started = time.perf_counter()
    reply = wait_reply(send(), what, timeout_sec)
    check(reply)
    return (reply.at - started) * 1e3


def wait_all(futures: Sequence[Future[Any]], timeout_sec: float, what: str) -> list[Any]:
    """Wait until every future has completed (one event, no polling); return their results."""
    remaining = [len(futures)]
    lock = threading.Lock()
    all_in = threading.Event()
    if not futures:
        return []

    def on_done(_: Future[Any]) -> None:
        with lock:
            remaining[0] -= 1
            if remaining[0] == 0:
                all_in.set()

    for future in futures:
        future.add_done_callback(on_done)
    if not all_in.wait(timeout_sec):
        raise BenchError(f'{what}: {remaining[0]} of {len(futures)} not in within {timeout_sec} s')
    return [future.result() for future in futures]


def last_reply_after(started: float, futures: Sequence[Future[Any]], what: str) -> float:
    """Seconds from `started` until the last of `futures` (completing with Replies) is in."""
    replies = wait_all(futures, config.BURST_TIMEOUT_SEC, what)
    return float(max(reply.at for reply in replies) - started)


def burst(send: Callable[[int], Future[Any]], count: int, what: str) -> tuple[float, list[Reply]]:
    """Send `count` requests at once; return the seconds until the last reply, and the replies."""
    started = time.perf_counter()
    futures = [send(index) for index in range(count)]
    replies = wait_all(futures, config.BURST_TIMEOUT_SEC, what)
    return max(reply.at for reply in replies) - started, replies
