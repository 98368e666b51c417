"""The trail of decisions the Task Manager took about one task, in words an operator reads.

A task keeps at most DECISIONS_PER_TASK_MAX entries (a request may reprioritize it again and
again): its first decisions, then one `omitted` entry counting those left out, then its
newest. A reason is kept up to REASON_MAX_CHARACTERS.
"""

import dataclasses
import json
from dataclasses import dataclass
from enum import StrEnum

from task_manager.core.bounds import DECISIONS_PER_TASK_MAX, REASON_MAX_CHARACTERS, cut_text

KEPT_FIRST = DECISIONS_PER_TASK_MAX // 2
"""The first decisions a task keeps; the newest fill the rest, less the `omitted` entry."""


class DecisionKind(StrEnum):
    QUEUED = 'queued'
    STARTED = 'started'
    """Started after a wait in the queue, or by pre-empting other tasks."""
    REFUSED = 'refused'
    PREEMPTED = 'preempted'
    TIMEOUT = 'timeout'
    RETRY = 'retry'
    REPRIORITIZED = 'reprioritized'
    OMITTED = 'omitted'
    """No decision: where decisions were left out, and (`omitted`) how many."""


@dataclass(frozen=True)
class DecisionNote:
    """One decision: when, which, and why (naming the other party)."""

    at: float
    decision: DecisionKind
    reason: str
    omitted: int = 0
    """Of an OMITTED entry: the decisions left out in its place."""

    def to_dict(self) -> dict[str, object]:
        entry: dict[str, object] = {
            'at': self.at,
            'decision': str(self.decision),
            'reason': self.reason,
        }
        if self.omitted:
            entry['omitted'] = self.omitted
        return entry


def new_note(at: float, decision: DecisionKind, reason: str) -> DecisionNote:
    """A decision, its reason cut to REASON_MAX_CHARACTERS."""
    return DecisionNote(at, decision, cut_text(reason, REASON_MAX_CHARACTERS))


def keep_note(notes: list[DecisionNote], note: DecisionNote) -> None:
    """Append `note` to a task's `notes`, which keep at most DECISIONS_PER_TASK_MAX entries:
    beyond them, the oldest after the first KEPT_FIRST is counted in the `omitted` entry."""
    if len(notes) < DECISIONS_PER_TASK_MAX:
        notes.append(note)
        return
    marker = notes[KEPT_FIRST]
    left_out = notes.pop(KEPT_FIRST + 1)
    # the first time, the entry in the marker's place is left out too
    count = marker.omitted + 1 if marker.decision is DecisionKind.OMITTED else 2
    kept_newest = DECISIONS_PER_TASK_MAX - KEPT_FIRST - 1
    notes[KEPT_FIRST] = dataclasses.replace(
        marker,
        at=left_out.at,
        decision=DecisionKind.OMITTED,
        reason=(
            f'{count} decisions left out here: a task keeps its first {KEPT_FIRST} '
            f'and its newest {kept_newest}'
        ),
        omitted=count,
    )
    notes.append(note)


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
                DecisionNote(
                    float(item['at']),
                    DecisionKind(item['decision']),
                    str(item['reason']),
                    int(item.get('omitted', 0)),
                )
            )
        except (KeyError, TypeError, ValueError, AttributeError):
            continue
    return notes
