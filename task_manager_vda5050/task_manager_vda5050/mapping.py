"""The mapping from VDA 5050 to the robot's tasks, read from a YAML file (docs/vda5050.md).

    navigation:                       # reaching a node's nodePosition
      task_name: navigation/navigate_to_pose
      task_data: {x: $x, y: $y, theta: $theta}
      defaults: {theta: 0.0}          # nodePosition.theta is optional
    actions:                          # actionType -> task
      take_photo:
        task_name: camera/take_photo
        task_data: {camera: $camera}  # $key: the value of the actionParameter `key`
        defaults: {camera: ''}        # a parameter without a default is required
        scopes: [INSTANT, NODE, EDGE]
        description: Take a photo with one of the robot's cameras.
    vehicle:                          # factsheet sections, as the standard spells them
      typeSpecification: {seriesName: demo, agvKinematic: DIFF, ...}
    position:                         # agvPosition from the navigation task's feedback/result
      x: x
      y: y
      theta: theta
      map_id: demo
      initial: {x: 0.0, y: 0.0, theta: 0.0}

A template value that is a string `$name` is replaced by the value of `name` (its JSON type
kept); any other value is taken as it is.
"""

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import yaml

SCOPES = ('INSTANT', 'NODE', 'EDGE')
REPORTED = ('batteryState', 'safetyState', 'operatingMode')
DEMO_MAPPING = Path(__file__).resolve().parents[1] / 'params' / 'demo_mapping.yaml'
"""The mapping of the demo robot (`make vda5050`, the tests)."""


class MappingError(ValueError):
    """A mapping file that cannot be used; the message names the entry."""


class MissingValueError(KeyError):
    """A template names a value that neither the message nor the defaults give."""


@dataclass(frozen=True)
class TaskTemplate:
    """A task, its data built from named values (a node's position, an action's parameters)."""

    task_name: str
    task_data: dict[str, Any] = field(default_factory=dict)
    defaults: dict[str, Any] = field(default_factory=dict)

    def data(self, values: dict[str, Any]) -> dict[str, Any]:
        """The task data for `values`; MissingValueError names a required value not given."""
        given = {**self.defaults, **values}
        return {key: _fill(template, given) for key, template in self.task_data.items()}

    @property
    def names(self) -> list[str]:
        """The names its template uses."""
        return sorted({v[1:] for v in self.task_data.values() if _is_placeholder(v)})


@dataclass(frozen=True)
class ActionMapping(TaskTemplate):
    """An actionType's task, the scopes it may be used in, and words for the factsheet."""

    scopes: tuple[str, ...] = SCOPES
    description: str = ''


@dataclass(frozen=True)
class PositionSource:
    """Where agvPosition comes from: the navigation task's feedback and result fields."""

    x: str = 'x'
    y: str = 'y'
    theta: str = 'theta'
    map_id: str = 'map'
    """The mapId the position is given on."""
    initial: dict[str, float] | None = None
    """The pose before the first navigation (None: not initialized until then)."""


@dataclass(frozen=True)
class Mapping:
    navigation: TaskTemplate
    actions: dict[str, ActionMapping] = field(default_factory=dict)
    """key: actionType."""
    position: PositionSource | None = None
    reported: dict[str, Any] = field(default_factory=dict)
    """Fixed values of state: batteryState, safetyState, operatingMode (the defaults: full
    and not charging, no e-stop, AUTOMATIC)."""
    vehicle: dict[str, Any] = field(default_factory=dict)
    """The factsheet's typeSpecification, physicalParameters, agvGeometry and
    loadSpecification, as given (defaults for those not given)."""

    def action(self, action_type: str, scope: str) -> ActionMapping | None:
        """The mapping of `action_type` in `scope`, or None when there is none."""
        mapped = self.actions.get(action_type)
        return mapped if mapped is not None and scope in mapped.scopes else None


def _is_placeholder(value: Any) -> bool:
    return isinstance(value, str) and value.startswith('$') and len(value) > 1


def _fill(template: Any, values: dict[str, Any]) -> Any:
    if not _is_placeholder(template):
        return template
    name = template[1:]
    if name not in values:
        raise MissingValueError(name)
    return values[name]


def read_mapping(path: Path) -> Mapping:
    try:
        loaded = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as error:
        raise MappingError(f'cannot read the mapping file {path}: {error}') from None
    if not isinstance(loaded, dict):
        raise MappingError(f'the mapping file {path} must hold a mapping')
    return mapping_of(loaded)


def mapping_of(values: dict[str, Any]) -> Mapping:
    allowed = {'navigation', 'actions', 'position', 'vehicle', 'reported'}
    if unknown := sorted(set(values) - allowed):
        raise MappingError(f'unknown keys {unknown}; allowed: {sorted(allowed)}')
    reported = values.get('reported') or {}
    if not isinstance(reported, dict) or set(reported) - set(REPORTED):
        raise MappingError(f'reported: a mapping of {", ".join(REPORTED)}')
    if not isinstance(values.get('vehicle') or {}, dict):
        raise MappingError('vehicle: a mapping of factsheet sections')
    if not isinstance(values.get('navigation'), dict):
        raise MappingError('navigation: a mapping with task_name and task_data is required')
    navigation = _template(TaskTemplate, 'navigation', values['navigation'])
    actions = values.get('actions') or {}
    if not isinstance(actions, dict):
        raise MappingError('actions: a mapping of actionType to its task')
    position = values.get('position')
    return Mapping(
        navigation=navigation,
        actions={str(k): _template(ActionMapping, f'actions.{k}', v) for k, v in actions.items()},
        position=None if position is None else _position(position),
        vehicle=dict(values.get('vehicle') or {}),
        reported=dict(reported),
    )


T = TypeVar('T', bound=TaskTemplate)


def _template(kind: type[T], where: str, values: Any) -> T:
    if not isinstance(values, dict) or not isinstance(values.get('task_name'), str):
        raise MappingError(f'{where}: a mapping with a task_name')
    extra = {'scopes', 'description'} if kind is ActionMapping else set()
    allowed = {'task_name', 'task_data', 'defaults', *extra}
    if unknown := sorted(set(values) - allowed):
        raise MappingError(f'{where}: unknown keys {unknown}; allowed: {sorted(allowed)}')
    for key in ('task_data', 'defaults'):
        if not isinstance(values.get(key) or {}, dict):
            raise MappingError(f'{where}.{key}: a mapping')
    options: dict[str, Any] = {}
    if kind is ActionMapping:
        scopes = tuple(str(s).upper() for s in values.get('scopes') or SCOPES)
        if bad := [s for s in scopes if s not in SCOPES]:
            raise MappingError(f'{where}.scopes: {bad} not among {list(SCOPES)}')
        options = {'scopes': scopes, 'description': str(values.get('description') or '')}
    return kind(
        task_name=values['task_name'],
        task_data=dict(values.get('task_data') or {}),
        defaults=dict(values.get('defaults') or {}),
        **options,
    )


def _position(values: Any) -> PositionSource:
    if not isinstance(values, dict):
        raise MappingError('position: a mapping of x, y, theta, map_id, initial')
    allowed = {'x', 'y', 'theta', 'map_id', 'initial'}
    if unknown := sorted(set(values) - allowed):
        raise MappingError(f'position: unknown keys {unknown}; allowed: {sorted(allowed)}')
    initial = values.get('initial')
    if initial is not None and not (
        isinstance(initial, dict) and all(isinstance(initial.get(k), int | float) for k in 'xy')
    ):
        raise MappingError('position.initial: a mapping with numbers x, y (and theta)')
    names = {k: str(values[k]) for k in ('x', 'y', 'theta', 'map_id') if k in values}
    pose = None if initial is None else {k: float(initial.get(k, 0.0)) for k in ('x', 'y', 'theta')}
    return PositionSource(**names, initial=pose)
