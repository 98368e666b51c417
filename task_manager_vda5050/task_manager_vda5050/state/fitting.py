"""A state made to fit the broker's packet limit: the last guard before it is published (pure).

Every part of state is bounded (what it echoes is cut, its lists are capped), yet its nodes,
edges and actions with their descriptions may together be more than the broker takes (1 MiB,
or what its CONNACK says): a larger message makes the broker disconnect the vehicle, at each
state, for good. So a state too large goes out shortened: first without the descriptions;
then, while still too large, half of its largest list is left out at a time (the ended actions
first, the oldest first, then the newest not ended; the farthest nodes and edges; the oldest
errors and information). An information `stateShortened` says what was left out.
"""

import json
from typing import Any

from task_manager_vda5050.state.vehicle_state import ENDED

SHORTENED = 'stateShortened'
"""The infoType of the information saying what a shortened state left out."""
NOTE_BYTES = 1024
"""Room kept for that information."""
DESCRIPTIONS = ('actionDescription', 'resultDescription', 'nodeDescription', 'edgeDescription')
DESCRIBED = ('actionStates', 'nodeStates', 'edgeStates')
LISTS = ('actionStates', 'nodeStates', 'edgeStates', 'errors', 'information')


def size(document: Any) -> int:
    """The bytes of `document` as the link sends it (JSON, ASCII)."""
    return len(json.dumps(document))


def shortened(document: dict[str, Any], max_bytes: int) -> tuple[dict[str, Any], str]:
    """`document` when its JSON takes at most `max_bytes`; else a copy shortened to fit (if
    anything can make it fit) and words saying what it leaves out ('' when nothing)."""
    if size(document) <= max_bytes:
        return document, ''
    short = {**document, **{name: [_undescribed(i) for i in document[name]] for name in DESCRIBED}}
    # key: a list's name, value: how many of its items were left out
    left_out: dict[str, int] = {}
    while size(short) > max_bytes - NOTE_BYTES:
        sizes = {name: size(short[name]) for name in LISTS if short[name]}
        if not sizes:
            break
        name = max(sizes, key=sizes.__getitem__)
        count = (len(short[name]) + 1) // 2
        short[name] = _without(name, short[name], count)
        left_out[name] = left_out.get(name, 0) + count
    words = ', '.join(['descriptions', *(f'{n} {name}' for name, n in left_out.items())])
    note: dict[str, Any] = {
        'infoType': SHORTENED,
        'infoLevel': 'INFO',
        'infoDescription': f'state over the {max_bytes} bytes the broker takes; left out: {words}',
    }
    if left_out:
        note['infoReferences'] = [
            {'referenceKey': name, 'referenceValue': str(n)} for name, n in left_out.items()
        ]
    short['information'] = [*short['information'], note]
    return short, words


def _undescribed(item: dict[str, Any]) -> dict[str, Any]:
    bare = {k: v for k, v in item.items() if k not in DESCRIPTIONS}
    position = bare.get('nodePosition')
    if isinstance(position, dict) and 'mapDescription' in position:
        bare['nodePosition'] = {k: v for k, v in position.items() if k != 'mapDescription'}
    return bare


def _without(name: str, items: list[dict[str, Any]], count: int) -> list[dict[str, Any]]:
    """`items` of the list `name` but `count` of them."""
    if name in ('nodeStates', 'edgeStates'):
        return items[: len(items) - count]
    if name != 'actionStates':
        return items[count:]
    ended = [i for i, a in enumerate(items) if a['actionStatus'] in ENDED]
    not_ended = [i for i, a in enumerate(items) if a['actionStatus'] not in ENDED]
    gone = set((ended + not_ended[::-1])[:count])
    return [a for i, a in enumerate(items) if i not in gone]
