"""The client's view of message fields: stamps as aware datetimes, JSON text as dicts."""

import json
from datetime import UTC, datetime, timedelta
from typing import Any


def datetime_of(stamp: Any) -> datetime | None:
    """A builtin_interfaces/Time as a timezone-aware (UTC) datetime; None for zero (not yet)."""
    return _datetime(stamp.sec, stamp.nanosec)


def datetime_of_json(value: Any) -> datetime | None:
    """A Time in a result's JSON (`{"sec": ..., "nanosec": ...}`) as datetime_of does; None
    for zero or anything else."""
    if not isinstance(value, dict):
        return None
    sec, nanosec = value.get('sec', 0), value.get('nanosec', 0)
    if not all(isinstance(n, int) and not isinstance(n, bool) for n in (sec, nanosec)):
        return None
    return _datetime(sec, nanosec)


def _datetime(sec: int, nanosec: int) -> datetime | None:
    if sec == 0 and nanosec == 0:
        return None
    return datetime.fromtimestamp(sec, UTC) + timedelta(microseconds=nanosec // 1000)


def datetime_of_epoch(seconds: float) -> datetime:
    """Epoch seconds as a timezone-aware (UTC) datetime."""
    return datetime.fromtimestamp(seconds, UTC)


def json_object(text: str) -> dict[str, Any]:
    """A JSON object from a message field; anything else is kept as `{"raw": text}`."""
    try:
        value = json.loads(text or '{}')
    except json.JSONDecodeError:
        return {'raw': text}
    return value if isinstance(value, dict) else {'raw': text}


def json_text(data: dict[str, Any] | str | None) -> str:
    """Task data as the JSON text a message carries (text is passed on as it is)."""
    return data if isinstance(data, str) else json.dumps(data or {})
