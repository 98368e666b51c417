"""Replies time-stamped as they arrive, and bounded waits for them."""

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, cast

from rclpy.task import Future

from bench.harness import config
from task_manager.testing.harness import WaitTimeoutError, wait_for_future


class BenchError(RuntimeError):
    """A benchmark could not measure what it should (a timeout, a failed task)."""


@dataclass(frozen=True)
class Reply:
    """A response (action result or service response) and when it arrived (perf_counter)."""

    at: float
    response: Any


def stamped(target: Future[Any]) -> Callable[[Future[Any]], None]:
    """A done callback completing `target` with the Reply of the future it is called with."""

    def on_done(future: Future[Any]) -> None:
        target.set_result(Reply(time.perf_counter(), future.result()))

    return on_done


def wait_reply(
    future: Future[Any], what: str, timeout_sec: float = config.SAMPLE_TIMEOUT_SEC
) -> Reply:
    try:
        return cast(Reply, wait_for_future(future, timeout_sec, what))
    except WaitTimeoutError as error:
        raise BenchError(str(error)) from error
