"""The official VDA 5050 JSON schemas, and the problems of a message against them.

The schema files are the ones PyPI's `vda5050-sdk` (0.2.0) bundles: the 2.1.0 tag of the
standard's repository, byte for byte. Only the files are taken from it (behind this module,
so that another source can replace it); the SDK's models and clients are not used.

The 2.0.0 instantActions schema names the list `instantActions` and each action's type
`actionName` (errors of that tag, fixed in 2.1.0); master controls in the field send either,
so an inbound instantActions message is read in both spellings and validated as 2.1.0's.
What else an inbound message must be is inbound.py's.
"""

import importlib.util
import json
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import jsonschema

from task_manager.core.bounds import cut_text

# key: the topic, value: its schema's file name in the SDK's folder
SCHEMA_FILES = {
    'order': 'order.json',
    'instantActions': 'instantActions.json',
    'state': 'state.json',
    'connection': 'connection.json',
    'factsheet': 'factsheet.json',
    'visualization': 'visualization.json',
}


@dataclass(frozen=True)
class Invalid:
    """Why a message is not acted on: its first problem, and the field it is in."""

    field: str
    """The path of the field, e.g. `nodes/0/sequenceId` ('' for the whole message)."""
    message: str


def schema_folder() -> Path:
    """The SDK's folder of schema files, found without importing the SDK (its models and
    clients are not needed here)."""
    spec = importlib.util.find_spec('vda5050')
    if spec is None or spec.origin is None:
        raise ModuleNotFoundError('vda5050-sdk is not installed: it holds the VDA 5050 schemas')
    return Path(spec.origin).parent / 'validation' / 'schemas'


@cache
def schema(topic: str) -> dict[str, Any]:
    loaded: dict[str, Any] = json.loads((schema_folder() / SCHEMA_FILES[topic]).read_text())
    return loaded


@cache
def _validator(topic: str) -> Any:
    document = schema(topic)
    kind = jsonschema.validators.validator_for(document)
    return kind(document, format_checker=kind.FORMAT_CHECKER)


def problems(topic: str, document: Any) -> list[Invalid]:
    """Every problem of `document` against `topic`'s 2.1.0 schema, the deepest first (its
    message repeats at most a cut of the value at fault)."""
    errors = sorted(_validator(topic).iter_errors(document), key=lambda e: -len(e.path))
    return [
        Invalid(cut_text('/'.join(str(p) for p in error.path)), cut_text(error.message))
        for error in errors
    ]


def instant_actions_of_2_0(document: Any) -> Any:
    """A 2.0.0-tag instantActions message (`instantActions`, `actionName`) as 2.1.0 spells it;
    any other document unchanged."""
    if not isinstance(document, dict):
        return document
    if 'actions' not in document and 'instantActions' in document:
        document = {('actions' if k == 'instantActions' else k): v for k, v in document.items()}
    if isinstance(document.get('actions'), list):
        document = {**document, 'actions': _renamed(document['actions'])}
    return document


def _renamed(actions: Any) -> Any:
    if not isinstance(actions, list):
        return actions
    return [
        {
            ('actionType' if k == 'actionName' and 'actionType' not in a else k): v
            for k, v in a.items()
        }
        if isinstance(a, dict)
        else a
        for a in actions
    ]
