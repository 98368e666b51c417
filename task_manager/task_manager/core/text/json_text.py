"""Compact JSON text of results and feedback; NaN and infinities (which JSON cannot hold) become
null rather than failing."""

import json
import math
from typing import Any


def _nulls(value: Any) -> Any:
    """Replace non-finite floats by None, recursively."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: _nulls(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_nulls(item) for item in value]
    return value


def compact_json(data: dict[str, Any]) -> str:
    try:
        return json.dumps(data, allow_nan=False, ensure_ascii=False, separators=(',', ':'))
    except ValueError:
        return json.dumps(_nulls(data), allow_nan=False, ensure_ascii=False, separators=(',', ':'))
