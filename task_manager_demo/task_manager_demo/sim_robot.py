"""The simulated robot `sim_robot`: navigate, spin, dock, take photos and upload them, as real
servers do.

One base moves at a time. A timer advances the current motion and publishes its feedback;
each goal's execute callback is a coroutine awaiting the end of its motion, so no thread
waits per goal. A new navigate, spin or dock goal pre-empts the running one (ABORTED); a
cancelled goal stops the robot where it is and ends CANCELED. The uplink drops as many uploads
in a row as a request says, so that a task declared with retries shows its attempts.
"""

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from typing import Any

import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.action.server import ActionServer, CancelResponse, GoalResponse, ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.event_handler import EventHandler
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
from task_manager_demo_msgs.action import Dock, NavigateToPose, Spin
from task_manager_demo_msgs.srv import TakePhoto, UploadPhotos

from task_manager.process_setup import (
    block_stop_signals,
    end_within,
    on_stop_signal,
    prepare_ros_process,
)
from task_manager_demo.motion import DriveToPose, Motion, Pose, Speeds, SpinBy
from task_manager_demo.robot_interface import (
    DOCK_ACTION,
    NAVIGATE_ACTION,
    ROBOT_READY_LOG,
    SPIN_ACTION,
    TAKE_PHOTO_SERVICE,
    UPLOAD_PHOTOS_SERVICE,
)

NODE_NAME = 'sim_robot'
DEFAULT_CAMERA = 'front'
BROKEN_CAMERA = 'broken'
EXIT_CONFIGURATION_ERROR = 2

# parameter name -> default; all floats (an integer in a parameters file is accepted too)
FLOAT_PARAMETERS = {
    'linear_speed': 0.5,
    'angular_speed': 1.0,
    'update_rate': 10.0,
    'initial_x': 0.0,
    'initial_y': 0.0,
    'initial_theta': 0.0,
    'dock_x': 0.0,
    'dock_y': 0.0,
    'dock_theta': 0.0,
}
POSITIVE_PARAMETERS = ('linear_speed', 'angular_speed', 'update_rate')

# The camera keeps every request of a burst (hundreds of photos from a fleet manager): with
# the services' default depth, 10, requests beyond it are dropped while it is busy, and
# their tasks would end ERROR only at the Task Manager's service_response_timeout.
REQUEST_BURST_QOS = QoSProfile(depth=1000)


class ConfigurationError(ValueError):
    """A parameter of the robot is unusable."""


class Outcome(Enum):
    """How a motion ended, and so its goal."""

    SUCCEEDED = 'succeeded'
    CANCELED = 'canceled'
    PREEMPTED = 'pre-empted'


def finish_goal(goal_handle: ServerGoalHandle[Any, Any, Any], outcome: Outcome) -> None:
    if outcome is Outcome.SUCCEEDED:
        goal_handle.succeed()
    elif outcome is Outcome.CANCELED:
        goal_handle.canceled()
    else:
        goal_handle.abort()


@dataclass
class _Drive:
    """The motion the base is carrying out, for one goal."""

    goal_handle: ServerGoalHandle[Any, Any, Any]
    motion: Motion
    feedback: Callable[[Pose], Any]
    outcome: Future[Outcome]


class Base:
    """The robot's single base: its pose and the one motion it is carrying out."""

    def __init__(self, pose: Pose, dt: float) -> None:
        self.pose = pose
        self.dt = dt
        self._drive: _Drive | None = None

    def start(
        self,
        goal_handle: ServerGoalHandle[Any, Any, Any],
        motion: Motion,
        feedback: Callable[[Pose], Any],
    ) -> Future[Outcome]:
        """Start `motion` for `goal_handle`, pre-empting the running one; returns its Outcome."""
        self._end(Outcome.PREEMPTED)
        self._drive = _Drive(goal_handle, motion, feedback, Future())
        return self._drive.outcome

    def tick(self) -> None:
        """Advance the running motion by one time step and publish its feedback."""
        drive = self._drive
        if drive is None:
            return
        if drive.goal_handle.is_cancel_requested:
            self._end(Outcome.CANCELED)
            return
        self.pose = drive.motion.step(self.pose, self.dt)
        drive.goal_handle.publish_feedback(drive.feedback(self.pose))
        if drive.motion.finished(self.pose):
            self._end(Outcome.SUCCEEDED)

    def _end(self, outcome: Outcome) -> None:
        if self._drive is not None:
            self._drive.outcome.set_result(outcome)
            self._drive = None


def _goal_is_finite(request: Any) -> bool:
    fields = request.get_fields_and_field_types()
    return all(
        math.isfinite(getattr(request, name)) for name, kind in fields.items() if kind == 'double'
    )


class SimRobot(Node):
    """Serves /navigate_to_pose, /spin, /dock, /take_photo and /upload_photos for a robot on
    a plane.

    Parameters: linear_speed (m/s, 0.5), angular_speed (rad/s, 1.0), update_rate (Hz, 10.0),
    initial_x/_y/_theta (the start pose, the origin), dock_id ("home") and dock_x/_y/_theta
    (the dock's pose, the origin: the robot starts on its dock).
    """

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        values = {
            name: self._float_parameter(name, default) for name, default in FLOAT_PARAMETERS.items()
        }
        # a string: rclpy refuses an override of another type than the default's
        self.dock_id: str = self.declare_parameter('dock_id', 'home').value
        self.speeds = Speeds(values['linear_speed'], values['angular_speed'])
        self.dock_pose = Pose(values['dock_x'], values['dock_y'], values['dock_theta'])
        start = Pose(values['initial_x'], values['initial_y'], values['initial_theta'])
        self.base = Base(start, 1.0 / values['update_rate'])
        self._photos_taken = 0
        self._photos_uploaded = 0
        self._uploads_dropped_in_a_row = 0
        self.create_timer(self.base.dt, self.base.tick)
        group = ReentrantCallbackGroup()
        self._action_server(NavigateToPose, NAVIGATE_ACTION, self._navigate, group)
        self._action_server(Spin, SPIN_ACTION, self._spin, group)
        self._action_server(Dock, DOCK_ACTION, self._dock, group)
        self.create_service(
            TakePhoto,
            TAKE_PHOTO_SERVICE,
            self._take_photo,
            qos_profile=REQUEST_BURST_QOS,
            callback_group=group,
        )
        self.create_service(
            UploadPhotos, UPLOAD_PHOTOS_SERVICE, self._upload_photos, callback_group=group
        )
        self.get_logger().info(
            f'{ROBOT_READY_LOG} at {self.base.pose}: serving {NAVIGATE_ACTION}, {SPIN_ACTION}, '
            f'{DOCK_ACTION}, {TAKE_PHOTO_SERVICE}, {UPLOAD_PHOTOS_SERVICE} '
            f'(dock "{self.dock_id}" at {self.dock_pose})'
        )

    def _float_parameter(self, name: str, default: float) -> float:
        descriptor = ParameterDescriptor(dynamic_typing=True)
        raw: object = self.declare_parameter(name, default, descriptor).value
        if isinstance(raw, bool) or not isinstance(raw, int | float):
            raise ConfigurationError(f'parameter {name} must be a number, got {raw!r}')
        value = float(raw)
        if name in POSITIVE_PARAMETERS and not value > 0.0:
            raise ConfigurationError(f'parameter {name} must be > 0, got {value}')
        return value

    def _action_server(
        self, action_type: Any, topic: str, execute: Any, group: ReentrantCallbackGroup
    ) -> ActionServer[Any, Any, Any]:
        return ActionServer(
            self,
            action_type,
            topic,
            execute_callback=execute,
            goal_callback=lambda request: (
                GoalResponse.ACCEPT if _goal_is_finite(request) else GoalResponse.REJECT
            ),
            cancel_callback=lambda _: CancelResponse.ACCEPT,
            callback_group=group,
        )

    async def _drive(
        self, what: str, goal_handle: ServerGoalHandle[Any, Any, Any], motion: Motion, feedback: Any
    ) -> Outcome:
        outcome = await self.base.start(goal_handle, motion, feedback)
        if outcome is None:  # only for a cancelled future, and the base cancels none
            raise RuntimeError(f'{what}: the motion ended without an outcome')
        finish_goal(goal_handle, outcome)
        self.get_logger().info(f'{what}: {outcome.value} at {self.base.pose}')
        return outcome

    async def _navigate(
        self, goal_handle: ServerGoalHandle[Any, Any, Any]
    ) -> NavigateToPose.Result:
        request = goal_handle.request
        motion = DriveToPose(Pose(request.x, request.y, request.theta), self.speeds)
        self.get_logger().info(f'navigate: from {self.base.pose} to {motion.goal}')

        def feedback(pose: Pose) -> NavigateToPose.Feedback:
            return NavigateToPose.Feedback(
                x=pose.x, y=pose.y, distance_remaining=motion.distance_remaining(pose)
            )

        await self._drive('navigate', goal_handle, motion, feedback)
        pose = self.base.pose
        return NavigateToPose.Result(x=pose.x, y=pose.y, theta=pose.theta)

    async def _spin(self, goal_handle: ServerGoalHandle[Any, Any, Any]) -> Spin.Result:
        motion = SpinBy(goal_handle.request.angle, self.speeds)
        self.get_logger().info(f'spin: {motion.angle:.2f} rad from {self.base.pose}')
        await self._drive(
            'spin',
            goal_handle,
            motion,
            lambda _: Spin.Feedback(angle_remaining=motion.remaining),
        )
        return Spin.Result(angle_travelled=motion.travelled)

    async def _dock(self, goal_handle: ServerGoalHandle[Any, Any, Any]) -> Dock.Result:
        dock_id = goal_handle.request.dock_id or self.dock_id
        if dock_id != self.dock_id:
            self.get_logger().error(f'dock: unknown dock "{dock_id}" (known: "{self.dock_id}")')
            goal_handle.abort()
            return Dock.Result(docked=False)
        motion = DriveToPose(self.dock_pose, self.speeds)
        self.get_logger().info(f'dock: from {self.base.pose} to dock "{dock_id}"')
        outcome = await self._drive(
            'dock',
            goal_handle,
            motion,
            lambda pose: Dock.Feedback(distance_remaining=motion.distance_remaining(pose)),
        )
        return Dock.Result(docked=outcome is Outcome.SUCCEEDED)

    def _take_photo(self, request: TakePhoto.Request, response: TakePhoto.Response) -> Any:
        camera = request.camera or DEFAULT_CAMERA
        if camera == BROKEN_CAMERA:
            response.message = f'camera "{camera}" does not respond'
            self.get_logger().error(f'take_photo: {response.message}')
            return response
        self._photos_taken += 1
        response.success = True
        response.photo_id = f'{camera}-{self._photos_taken:04d}'
        response.message = f'photo {response.photo_id} taken at {self.base.pose}'
        self.get_logger().info(f'take_photo: {response.message}')
        return response

    def _upload_photos(self, request: UploadPhotos.Request, response: UploadPhotos.Response) -> Any:
        """Drop the upload until `request.drops` uploads have failed in a row, else upload."""
        if self._uploads_dropped_in_a_row < request.drops:
            self._uploads_dropped_in_a_row += 1
            response.message = (
                f'the link dropped the upload ({self._uploads_dropped_in_a_row} of '
                f'{request.drops} in a row)'
            )
            self.get_logger().warning(f'upload_photos: {response.message}')
            return response
        self._uploads_dropped_in_a_row = 0
        response.photos_uploaded = self._photos_taken - self._photos_uploaded
        self._photos_uploaded = self._photos_taken
        response.success = True
        response.message = f'{response.photos_uploaded} photo(s) uploaded'
        self.get_logger().info(f'upload_photos: {response.message}')
        return response

    def destroy_node(self) -> None:
        """Destroy the action servers first: destroy_node leaves them to the GC."""
        for waitable in list(self.waitables):
            if isinstance(waitable, ActionServer | EventHandler):  # every kind this node has
                waitable.destroy()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Console script `task-manager-demo-robot`: run the simulated robot until SIGINT or SIGTERM
    (Ctrl-C), then end it cleanly: taken by a thread of ours, not by rclpy's handler, whose
    shutdown of the context from a thread of its own races the node's end (process_setup)."""
    block_stop_signals()
    prepare_ros_process()
    rclpy.init(
        args=args if args is not None else sys.argv,
        signal_handler_options=SignalHandlerOptions.NO,
    )
    node = None
    executor = SingleThreadedExecutor()
    try:
        node = SimRobot()
        executor.add_node(node)
        stopped: Future[bool] = Future()
        on_stop_signal(lambda: executor.create_task(stopped.set_result, True), NODE_NAME)
        executor.spin_until_future_complete(stopped)
    except ConfigurationError as error:
        rclpy.logging.get_logger(NODE_NAME).fatal(f'invalid configuration: {error}')
        return EXIT_CONFIGURATION_ERROR
    finally:
        end_within(lambda: _release(executor, node), 'task-manager-demo-robot', 0)
    return 0


def _release(executor: SingleThreadedExecutor, node: SimRobot | None) -> None:
    executor.shutdown()
    if node is not None:
        node.destroy_node()
    rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
