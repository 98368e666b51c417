"""A request's priority: its own, or its declaration's plus its source's."""

from collections.abc import Mapping
from typing import Any

from task_manager.core.errors import ConfigurationError

SOURCE_SEPARATOR = ':'
"""Parts a source: 'WEB:alice' is the source WEB, for user alice."""


def source_priority(source: str, source_priorities: Mapping[str, int]) -> int:
    """The priority of `source`: matched exactly, else by its part before the first ':'; else 0."""
    if source in source_priorities:
        return source_priorities[source]
    kind, separator, _ = source.partition(SOURCE_SEPARATOR)
    return source_priorities.get(kind, 0) if separator else 0


def effective_priority(
    spec_priority: int, source: str, source_priorities: Mapping[str, int], requested: int | None
) -> int:
    """The request's own priority when it gives one; else the declared one plus its source's."""
    if requested is not None:
        return requested
    return spec_priority + source_priority(source, source_priorities)


def parse_source_priorities(values: Mapping[str, Any]) -> dict[str, int]:
    """The node parameter `source_priorities` (key: source, value: priority), checked."""
    for source, value in values.items():
        if not isinstance(value, int) or isinstance(value, bool):
            raise ConfigurationError(
                f"parameter 'source_priorities.{source}' must be int (the priority of "
                f'source {source!r}), got {value!r}'
            )
    return dict(values)
