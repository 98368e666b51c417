"""wait_until_ready: a server found a moment after the wait begins ends it within 20 ms
(rclpy's own waits look every 0.25 s), and a missing one ends it at the timeout."""

import time

import pytest

from task_manager.rclpy_tools import server_wait
from task_manager.rclpy_tools.server_wait import LONGEST_GAP_SEC, wait_until_ready


def test_a_server_ready_at_once_ends_the_wait_without_sleeping(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    gaps: list[float] = []
    monkeypatch.setattr(f'{server_wait.__name__}.sleep', gaps.append)

    assert wait_until_ready(lambda: True, timeout_sec=5.0)

    assert gaps == []


def test_the_looks_come_often_at_first_and_never_more_than_20_ms_apart(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    gaps: list[float] = []
    monkeypatch.setattr(f'{server_wait.__name__}.sleep', gaps.append)

    assert wait_until_ready(lambda: len(gaps) == 30, timeout_sec=5.0)

    assert gaps[0] <= 0.001
    assert max(gaps) == LONGEST_GAP_SEC == 0.02
    assert gaps == sorted(gaps)  # then less often, so that a long wait costs little CPU


def test_a_missing_server_ends_the_wait_at_the_timeout() -> None:
    began = time.monotonic()

    assert not wait_until_ready(lambda: False, timeout_sec=0.2)

    assert 0.2 <= time.monotonic() - began < 2.0
