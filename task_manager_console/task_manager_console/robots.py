"""`RobotState`: what the console knows of one robot, from its bridge's retained documents
(`connection`, `tasks`, `active_tasks`) and its results.

Every document comes from a robot over the broker and is checked against the protocol's models
(`task_manager.protocol.mqtt`) before it changes anything: one that does not fit is
BadDocumentError, and the state stays as it was.
"""

from dataclasses import dataclass, field
from datetime import UTC, datetime
from enum import StrEnum
from typing import Any

from pydantic import ValidationError

from task_manager.core.bounds import cut_text
from task_manager.core.text.request_text import text_problem
from task_manager.protocol import mqtt
from task_manager.protocol.errors import describe

Document = dict[str, Any]


class ConnectionState(StrEnum):
    """A robot's connection, as its bridge (or the broker, for its last will) publishes it."""

    ONLINE = 'ONLINE'
    """Its bridge is connected to the broker."""
    OFFLINE = 'OFFLINE'
    """Its bridge stopped cleanly."""
    CONNECTIONBROKEN = 'CONNECTIONBROKEN'
    """Its bridge vanished: the broker published its last will."""


class BadDocumentError(ValueError):
    """A robot's document that does not fit the protocol; the message says why."""


@dataclass(frozen=True)
class RobotState:
    """One robot as the console sees it; a new value at each change (never changed in place)."""

    robot_id: str
    connection_state: ConnectionState = ConnectionState.OFFLINE
    since: datetime | None = None
    """When it entered its connection state (as the console saw it, or its document's
    timestamp when the console found it so); None before its first connection document."""
    task_manager_connected: bool = False
    """Whether its bridge reaches its Task Manager."""
    tasks: list[Document] = field(default_factory=list)
    """The tasks it declares (DeclaredTask documents)."""
    tasks_omitted: int = 0
    active: list[Document] = field(default_factory=list)
    """Its active tasks (Task documents): running, queued, paused, confirmations waiting."""
    active_omitted: int = 0
    """Active tasks its bridge left out of `active` to fit a message."""
    schedules: list[Document] = field(default_factory=list)
    """Its schedules (Schedule documents), as last asked."""
    last_result: Document | None = None
    """Its newest result stored (a fleet history document)."""
    results_stored: int = 0
    """Results of it stored since the console started."""
    bad_messages: int = 0
    """Messages of it that did not fit the protocol (ignored) since the console started."""

    @property
    def silent(self) -> bool:
        """Not heard as it should be: its bridge vanished (CONNECTIONBROKEN), or it is ONLINE
        but its bridge reaches no Task Manager."""
        if self.connection_state == ConnectionState.CONNECTIONBROKEN:
            return True
        return self.connection_state == ConnectionState.ONLINE and not self.task_manager_connected

    @property
    def online(self) -> bool:
        """ONLINE and reaching its Task Manager: it can take requests."""
        return self.connection_state == ConnectionState.ONLINE and self.task_manager_connected

    def declares(self, task_name: str) -> bool:
        return any(task.get('task_name') == task_name for task in self.tasks)

    def with_fields(self, **fields: Any) -> 'RobotState':
        """A copy with these fields changed (dataclasses.replace, without its checks: it runs
        for every message of every robot)."""
        state = object.__new__(RobotState)
        state.__dict__.update(self.__dict__, **fields)
        return state

    def document(self) -> Document:
        """As JSON: every field, `silent` included, stamps as ISO 8601 text."""
        return {
            'robot_id': self.robot_id,
            'connection_state': str(self.connection_state),
            'since': None if self.since is None else self.since.isoformat(),
            'silent': self.silent,
            'task_manager_connected': self.task_manager_connected,
            'tasks': self.tasks,
            'tasks_omitted': self.tasks_omitted,
            'active': self.active,
            'active_omitted': self.active_omitted,
            'schedules': self.schedules,
            'last_result': self.last_result,
            'results_stored': self.results_stored,
            'bad_messages': self.bad_messages,
        }

    # ---- changes: each returns the new state ---------------------------------------------------

    def with_connection(self, document: object, now: datetime | None = None) -> 'RobotState':
        """After its `connection` document; `since` is `now` if the state changed while
        watched, else the document's timestamp (the first one seen)."""
        connection = _model(mqtt.Connection, document, 'connection')
        if connection.robot_id != self.robot_id:
            raise BadDocumentError(
                f'connection: robot_id {cut_text(connection.robot_id)!r} on the topic of '
                f'{cut_text(self.robot_id)!r}'
            )
        state = ConnectionState(connection.connection_state)
        since = self.since
        if self.since is None:
            since = connection.timestamp
        elif state != self.connection_state:
            since = now or datetime.now(UTC)
        return self.with_fields(
            connection_state=state,
            since=since,
            task_manager_connected=connection.task_manager_connected,
        )

    def with_tasks(self, document: object) -> 'RobotState':
        """After its `tasks` document (the declared tasks)."""
        declared = _model(mqtt.DeclaredTasks, document, 'tasks')
        tasks = [task.model_dump(mode='json') for task in declared.tasks]
        return self.with_fields(tasks=tasks, tasks_omitted=declared.omitted)

    def with_active(self, document: object) -> 'RobotState':
        """After its `active_tasks` document."""
        active = _model(mqtt.ActiveTasks, document, 'active_tasks')
        tasks = active.model_dump(mode='json', exclude_none=True, include={'tasks'})['tasks']
        return self.with_fields(active=tasks, active_omitted=active.omitted)


def robot_id_problem(robot_id: str) -> str:
    """Why `robot_id` may not name a robot (control characters, too long, a topic wildcard or
    level); empty if it may."""
    if problem := text_problem('robot_id', robot_id):
        return problem
    if not robot_id or any(character in robot_id for character in '+#/'):
        return f'robot_id {cut_text(robot_id)!r} must be one topic level, without + # /'
    return ''


def _model(model: Any, document: object, topic: str) -> Any:
    try:
        return model.model_validate(document)
    except ValidationError as error:
        message, _ = describe(error.errors())
        raise BadDocumentError(f'{topic}: {message}') from None
