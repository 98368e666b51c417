"""The topics of one robot, `<prefix>/<robot_id>/<name>` (VDA 5050's layout, one level less:
the robot id stands for its manufacturer/serialNumber pair)."""

from dataclasses import dataclass
from enum import StrEnum

ANY_ROBOT = '+'


class TopicName(StrEnum):
    """The last level of a robot's topics: the one home of their names (docs/fleet-mqtt.md)."""

    REQUEST = 'request'
    REPLY = 'reply'
    RESULT = 'result'
    EVENT = 'event'
    ACTIVE_TASKS = 'active_tasks'
    TASKS = 'tasks'
    CONNECTION = 'connection'
    DEAD_LETTER = 'dead_letter'


OUTGOING = tuple(name for name in TopicName if name is not TopicName.REQUEST)
"""The topics a robot writes (its bridge); the cloud writes only `request`."""
FOLLOWED = (
    TopicName.REPLY,
    TopicName.RESULT,
    TopicName.DEAD_LETTER,
    TopicName.TASKS,
    TopicName.ACTIVE_TASKS,
    TopicName.CONNECTION,
)
"""The topics a FleetClient follows of every robot (and `event` when it follows events); the
connection last, so that the retained state of a robot is there when it is seen ONLINE."""


@dataclass(frozen=True)
class Topics:
    prefix: str
    robot_id: str

    def topic(self, name: str) -> str:
        return f'{self.prefix}/{self.robot_id}/{name}'

    @property
    def request(self) -> str:
        """cloud -> robot, QoS 1: one operation per message."""
        return self.topic(TopicName.REQUEST)

    @property
    def reply(self) -> str:
        """robot -> cloud, QoS 1: the answer to each request."""
        return self.topic(TopicName.REPLY)

    @property
    def result(self) -> str:
        """robot -> cloud, QoS 1: one message per ended task, in sequence order."""
        return self.topic(TopicName.RESULT)

    @property
    def event(self) -> str:
        """robot -> cloud, QoS 0: every change of every task."""
        return self.topic(TopicName.EVENT)

    @property
    def active_tasks(self) -> str:
        """robot -> cloud, retained: the active tasks."""
        return self.topic(TopicName.ACTIVE_TASKS)

    @property
    def tasks(self) -> str:
        """robot -> cloud, retained: the declared tasks and their goal schemas."""
        return self.topic(TopicName.TASKS)

    @property
    def connection(self) -> str:
        """robot -> cloud, retained, QoS 1: ONLINE, OFFLINE or (last will) CONNECTIONBROKEN."""
        return self.topic(TopicName.CONNECTION)

    @property
    def dead_letter(self) -> str:
        """robot -> cloud, QoS 1: a request that could not be answered (no request_id), and why."""
        return self.topic(TopicName.DEAD_LETTER)

    def robot_of(self, topic: str) -> str:
        """The robot id in a topic of this layout (of a subscription to ANY_ROBOT)."""
        return topic[len(self.prefix) + 1 :].split('/', 1)[0]
