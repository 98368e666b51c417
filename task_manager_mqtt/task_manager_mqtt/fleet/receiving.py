"""`FleetReceiver`: what every robot sends the cloud, read and handed on: the replies to its
requests and the results of its tasks (to the futures waiting for them, and to the callbacks),
its task events and dead letters, its retained state documents (kept as a RobotView), and the
messages that cannot be read.

Each robot's results are told apart by sequence number and task id: one delivered twice (after
a reconnection) is passed on once, and a robot whose history began again is still heard
(fleet/passed_results.py). With `hold_results`, every delivery of a result is handed over
with the means to acknowledge it, and the broker keeps it until then.
"""

import logging
import threading
from collections.abc import Callable
from concurrent.futures import Future

from task_manager.protocol.strict_json import load_within
from task_manager_mqtt.fleet.passed_results import PassedResults
from task_manager_mqtt.fleet_types import Document, RobotView
from task_manager_mqtt.topics import ANY_ROBOT, TopicName, Topics

LOG = logging.getLogger('task_manager_mqtt.fleet')
Acknowledge = Callable[[], None]
HeldCallback = Callable[[str, Document, Acknowledge], None]


class FleetReceiver:
    """The messages of every robot under a prefix (`receive`, on the MQTT client's thread)."""

    def __init__(
        self,
        prefix: str,
        acknowledge: Callable[[int, int], object],
        *,
        hold_results: bool = False,
        max_message_bytes: int = 0,
    ) -> None:
        """`acknowledge(mid, qos)`: tell the broker a held result is kept (see FleetClient)."""
        self.prefix = prefix
        self.robots: dict[str, RobotView] = {}
        self.result_callbacks: list[Callable[[str, Document], None]] = []
        self.robot_callbacks: list[Callable[[RobotView], None]] = []
        self.event_callbacks: list[Callable[[str, Document], None]] = []
        self.dead_letter_callbacks: list[Callable[[str, Document], None]] = []
        self.held_callbacks: list[HeldCallback] = []
        self.state_callbacks: list[Callable[[str, str, Document | None], None]] = []
        self.bad_message_callbacks: list[Callable[[str, str, str], None]] = []
        self._all = Topics(prefix, ANY_ROBOT)
        self._acknowledge = acknowledge
        self._hold_results = hold_results
        self._max_message_bytes = max_message_bytes
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        """Notified at each change of a robot's view."""
        self._replies: dict[str, Future[Document]] = {}
        # key: (robot id, task id), value: its result, once it comes
        self._results: dict[tuple[str, str], Future[Document]] = {}
        # key: robot id, value: its results passed on lately
        self._passed: dict[str, PassedResults] = {}
        self._handlers: dict[str, Callable[[str, Document], None]] = {
            TopicName.REPLY: self._on_reply,
            TopicName.RESULT: self._on_result,
            TopicName.EVENT: self._on_event,
            TopicName.DEAD_LETTER: self._on_dead_letter,
        }

    # ---- what requests wait for ---------------------------------------------------------------

    def expect_reply(self, request_id: str, reply: Future[Document]) -> None:
        with self._lock:
            self._replies[request_id] = reply

    def take_reply(self, request_id: str) -> Future[Document] | None:
        """The future of a reply still awaited (no longer awaited then)."""
        with self._lock:
            return self._replies.pop(request_id, None)

    def expect_result(self, robot_id: str, task_id: str, result: Future[Document]) -> None:
        with self._lock:
            self._results[(robot_id, task_id)] = result

    def take_result(self, robot_id: str, task_id: str) -> Future[Document] | None:
        """The future of a result still awaited (no longer awaited then)."""
        with self._lock:
            return self._results.pop((robot_id, task_id), None)

    def wait_for(
        self, condition: Callable[[dict[str, RobotView]], bool], timeout_sec: float
    ) -> bool:
        """Wait until `condition(robots)` holds (checked at each change); whether it did."""
        with self._changed:
            return self._changed.wait_for(lambda: condition(self.robots), timeout_sec)

    # ---- on the MQTT client's thread ----------------------------------------------------------

    def receive(self, topic: str, payload: bytes, mid: int = 0, qos: int = 0) -> bool:
        """Pass a message on; whether a held result's acknowledgement was handed over."""
        name = topic.rsplit('/', 1)[-1]
        robot_id = self._all.robot_of(topic)
        limit = self._max_message_bytes
        if limit and len(payload) > limit:
            self._bad_message(robot_id, name, f'{len(payload)} bytes; at most {limit} are read')
            return False
        try:
            document = load_within(payload) if payload else None
        except ValueError as error:  # the robot's documents are checked as its requests are
            self._bad_message(robot_id, name, f'not JSON ({str(error)[:200]})')
            return False
        if not isinstance(document, dict | None):
            self._bad_message(robot_id, name, 'not a JSON object')
        elif name == TopicName.RESULT and self._hold_results and self.held_callbacks:
            if document is not None:
                self._on_held(robot_id, document, mid, qos)
                return True
        elif name in self._handlers:
            if document is not None:
                self._handlers[name](robot_id, document)
        else:
            self._on_robot_state(robot_id, name, document)
        return False

    def _bad_message(self, robot_id: str, name: str, why: str) -> None:
        if not self.bad_message_callbacks:
            LOG.warning('%s/%s/%s: %s, ignored', self.prefix, robot_id, name, why)
        for callback in self.bad_message_callbacks:
            callback(robot_id, name, why)

    def _on_held(self, robot_id: str, task: Document, mid: int, qos: int) -> None:
        """Every delivery to the held callbacks (then, once per sequence, to on_result's)."""

        def acknowledge() -> None:
            self._acknowledge(mid, qos)

        for callback in self.held_callbacks:
            callback(robot_id, task, acknowledge)
        self._on_result(robot_id, task)

    def _on_event(self, robot_id: str, document: Document) -> None:
        for callback in self.event_callbacks:
            callback(robot_id, document)

    def _on_dead_letter(self, robot_id: str, document: Document) -> None:
        for callback in self.dead_letter_callbacks:
            callback(robot_id, document)

    def _on_reply(self, _: str, document: Document) -> None:
        reply = self.take_reply(document.get('request_id', ''))
        if reply is not None:
            reply.set_result(document)

    def _on_result(self, robot_id: str, task: Document) -> None:
        sequence = int(task.get('sequence') or 0)
        task_id = str(task.get('task_id', ''))
        with self._lock:
            robot = self._robot(robot_id)
            if sequence:
                passed = self._passed.setdefault(robot_id, PassedResults())
                if not passed.first_time(sequence, task_id):
                    robot.duplicates += 1  # delivered again after a reconnection
                    return
                if sequence <= robot.last_sequence:
                    LOG.info(
                        '%s: result %d of task %s after result %d: a new history of the robot '
                        '(or a result that came late), passed on',
                        robot_id,
                        sequence,
                        task_id,
                        robot.last_sequence,
                    )
                robot.last_sequence = sequence
            result = self._results.pop((robot_id, task_id), None)
        if result is not None and not result.done():
            result.set_result(task)
        for callback in self.result_callbacks:
            callback(robot_id, task)

    def _on_robot_state(self, robot_id: str, name: str, document: Document | None) -> None:
        with self._changed:
            robot = self._robot(robot_id)
            if name == TopicName.CONNECTION:
                robot.connection = document
            elif name == TopicName.ACTIVE_TASKS:
                robot.active_tasks = (document or {}).get('tasks', [])
                omitted = (document or {}).get('omitted')
                robot.active_tasks_omitted = omitted if isinstance(omitted, int) else 0
            elif name == TopicName.TASKS:
                robot.tasks = (document or {}).get('tasks', [])
            self._changed.notify_all()
        for state_callback in self.state_callbacks:
            state_callback(robot_id, name, document)
        for callback in self.robot_callbacks:
            callback(robot)

    def _robot(self, robot_id: str) -> RobotView:
        robot = self.robots.get(robot_id)
        if robot is None:
            robot = self.robots[robot_id] = RobotView(robot_id)
        return robot
