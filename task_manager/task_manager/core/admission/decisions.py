"""The trail of decisions the Task Manager took about one task, in words an operator reads."""

import json
from dataclasses import dataclass
from enum import StrEnum


class DecisionKind(StrEnum):
    QUEUED = 'queued'
    STARTED = 'started'
    """Started after a wait in the queue, or by pre-empting other tasks."""
    REFUSED = 'refused'
    PREEMPTED = 'preempted'
    TIMEOUT = 'timeout'
    RETRY = 'retry'
    REPRIORITIZED = 'reprioritized'


@dataclass(frozen=True)
class DecisionNote:
    """One decision: when, which, and why (naming the other party)."""

    at: float
    decision: DecisionKind
    reason: str

    def to_dict(self) -> dict[str, object]:
        return {'at': self.at, 'decision': str(self.decision), 'reason': self.reason}


def decisions_to_json(notes: list[DecisionNote]) -> str:
    """Decisions as a compact JSON list ('[]' when none)."""
    return json.dumps([note.to_dict() for note in notes], separators=(',', ':'))


def decisions_from_json(text: str) -> list[DecisionNote]:
    """The inverse of decisions_to_json; unknown or broken entries are skipped."""
    try:
        items = json.loads(text or '[]')
    except json.JSONDecodeError:
        return []
    notes = []
    for item in items if isinstance(items, list) else []:
        try:
            notes.append(
                DecisionNote(float(item['at']), DecisionKind(item['decision']), str(item['reason']))
            )
        except (KeyError, TypeError, ValueError):
            continue
    return notes
