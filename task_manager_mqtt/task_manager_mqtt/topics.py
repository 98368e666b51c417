"""The topics of one robot, `<prefix>/<robot_id>/<name>` (VDA 5050's layout, one level less:
the robot id stands for its manufacturer/serialNumber pair)."""

from dataclasses import dataclass

ANY_ROBOT = '+'
OUTGOING = ('reply', 'result', 'event', 'active_tasks', 'tasks', 'connection', 'dead_letter')
"""The topics a robot writes (its bridge); the cloud writes only `request`."""


@dataclass(frozen=True)
class Topics:
    prefix: str
    robot_id: str

    def topic(self, name: str) -> str:
        return f'{self.prefix}/{self.robot_id}/{name}'

    @property
    def request(self) -> str:
        """cloud -> robot, QoS 1: one operation per message."""
        return self.topic('request')

    @property
    def reply(self) -> str:
        """robot -> cloud, QoS 1: the answer to each request."""
        return self.topic('reply')

    @property
    def result(self) -> str:
        """robot -> cloud, QoS 1: one message per ended task, in sequence order."""
        return self.topic('result')

    @property
    def event(self) -> str:
        """robot -> cloud, QoS 0: every change of every task."""
        return self.topic('event')

    @property
    def active_tasks(self) -> str:
        """robot -> cloud, retained: the active tasks."""
        return self.topic('active_tasks')

    @property
    def tasks(self) -> str:
        """robot -> cloud, retained: the declared tasks and their goal schemas."""
        return self.topic('tasks')

    @property
    def connection(self) -> str:
        """robot -> cloud, retained, QoS 1: ONLINE, OFFLINE or (last will) CONNECTIONBROKEN."""
        return self.topic('connection')

    @property
    def dead_letter(self) -> str:
        """robot -> cloud, QoS 1: a request that could not be answered (no request_id), and why."""
        return self.topic('dead_letter')

    def robot_of(self, topic: str) -> str:
        """The robot id in a topic of this layout (of a subscription to ANY_ROBOT)."""
        return topic[len(self.prefix) + 1 :].split('/', 1)[0]
