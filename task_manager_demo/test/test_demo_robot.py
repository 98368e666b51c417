"""The simulated robot as a process, driven over DDS by in-process rclpy clients."""

import itertools
import math
import signal
from collections.abc import Iterator
from typing import Any

import pytest
from action_msgs.msg import GoalStatus
from rclpy.action.client import ActionClient
from rclpy.client import Client
from task_manager_demo_msgs.action import Dock, NavigateToPose, Spin
from task_manager_demo_msgs.srv import TakePhoto, UploadPhotos

from task_manager.rclpy_tools.server_wait import wait_until_ready
from task_manager.testing.harness import RosHarness, wait_for_future
from task_manager_demo.robot_interface import (
    DOCK_ACTION,
    NAVIGATE_ACTION,
    ROBOT_READY_LOG,
    SPIN_ACTION,
    TAKE_PHOTO_SERVICE,
    UPLOAD_PHOTOS_SERVICE,
)
from task_manager_demo.testing import DemoProcess, FeedbackRecorder, robot_command

START_TIMEOUT_SEC = 20.0
TIMEOUT_SEC = 10.0
# Fast, so every motion takes well under a second.
ROBOT_PARAMETERS = (
    'linear_speed:=4.0',
    'angular_speed:=12.0',
    'update_rate:=20.0',
    'dock_x:=-0.5',
    'dock_y:=0.0',
    'dock_theta:=0.0',
)

pytestmark = pytest.mark.ros


@pytest.fixture(scope='module')
def robot() -> Iterator[DemoProcess]:
    process = DemoProcess('sim_robot', robot_command(*ROBOT_PARAMETERS))
    try:
        process.wait_for_line(ROBOT_READY_LOG, START_TIMEOUT_SEC)
        yield process
    finally:
        assert process.stop() == 0, process.output


class RobotClient:
    """Action and service clients of the robot on the test's node."""

    def __init__(self, ros: RosHarness) -> None:
        node = ros.node
        self._ros = ros
        self.navigate = ros.action_client(NavigateToPose, NAVIGATE_ACTION)
        self.spin = ros.action_client(Spin, SPIN_ACTION)
        self.dock = ros.action_client(Dock, DOCK_ACTION)
        self.take_photo: Client[TakePhoto.Request, TakePhoto.Response] = node.create_client(
            TakePhoto, TAKE_PHOTO_SERVICE
        )
        self.upload_photos: Client[UploadPhotos.Request, UploadPhotos.Response] = (
            node.create_client(UploadPhotos, UPLOAD_PHOTOS_SERVICE)
        )
        for client in (self.navigate, self.spin, self.dock):
            assert wait_until_ready(client.server_is_ready, TIMEOUT_SEC)
        assert wait_until_ready(self.take_photo.service_is_ready, TIMEOUT_SEC)
        assert wait_until_ready(self.upload_photos.service_is_ready, TIMEOUT_SEC)

    def send(self, client: ActionClient[Any, Any, Any], goal: Any) -> tuple[Any, FeedbackRecorder]:
        feedback = FeedbackRecorder()
        future = self._ros.send_goal(client, goal, feedback)
        handle = wait_for_future(future, TIMEOUT_SEC, 'goal response')
        assert handle.accepted
        return handle, feedback

    def result(self, handle: Any) -> Any:
        return wait_for_future(handle.get_result_async(), TIMEOUT_SEC, 'result')

    def go_to(self, x: float, y: float, theta: float = 0.0) -> Any:
        handle, _ = self.send(self.navigate, NavigateToPose.Goal(x=x, y=y, theta=theta))
        return self.result(handle)

    def photo(self, camera: str) -> TakePhoto.Response:
        future = self.take_photo.call_async(TakePhoto.Request(camera=camera))
        return wait_for_future(future, TIMEOUT_SEC, 'take_photo response')

    def upload(self, drops: int) -> UploadPhotos.Response:
        future = self.upload_photos.call_async(UploadPhotos.Request(drops=drops))
        return wait_for_future(future, TIMEOUT_SEC, 'upload_photos response')


@pytest.fixture(scope='module')
def client(robot: DemoProcess, ros_context: None) -> Iterator[RobotClient]:
    """One node and its clients for the module: each discovery of the robot takes a while."""
    ros = RosHarness('demo_robot_test_client')
    try:
        yield RobotClient(ros)
    finally:
        ros.close()


def non_increasing(values: list[float]) -> bool:
    return all(later <= earlier + 1e-9 for earlier, later in itertools.pairwise(values))


def test_navigate_reaches_the_goal_with_decreasing_distance(client: RobotClient) -> None:
    client.go_to(0.0, 0.0)
    handle, feedback = client.send(client.navigate, NavigateToPose.Goal(x=1.5, y=0.5, theta=1.0))

    response = client.result(handle)

    assert response.status == GoalStatus.STATUS_SUCCEEDED
    assert (response.result.x, response.result.y) == (1.5, 0.5)
    assert response.result.theta == pytest.approx(1.0)
    distances = [f.distance_remaining for f in feedback.snapshot()]
    assert len(distances) >= 5
    assert non_increasing(distances)
    assert distances[0] > distances[-1]


def test_cancelled_navigate_ends_canceled_and_the_robot_stops(client: RobotClient) -> None:
    client.go_to(0.0, 0.0)
    handle, feedback = client.send(client.navigate, NavigateToPose.Goal(x=20.0, y=0.0))
    feedback.wait_until(lambda msgs: any(m.x > 0.0 for m in msgs), TIMEOUT_SEC)

    wait_for_future(handle.cancel_goal_async(), TIMEOUT_SEC, 'cancel response')
    response = client.result(handle)

    assert response.status == GoalStatus.STATUS_CANCELED
    stopped_at = response.result
    assert 0.0 < stopped_at.x < 20.0
    # Going where the robot stopped takes no motion: it has not moved since the cancel.
    again, again_feedback = client.send(
        client.navigate, NavigateToPose.Goal(x=stopped_at.x, y=0.0, theta=stopped_at.theta)
    )
    assert client.result(again).status == GoalStatus.STATUS_SUCCEEDED
    again_feedback.wait_until(lambda msgs: len(msgs) > 0, TIMEOUT_SEC)
    assert all(f.distance_remaining == 0.0 for f in again_feedback.snapshot())


def test_new_navigate_goal_preempts_the_running_one(client: RobotClient) -> None:
    client.go_to(0.0, 0.0)
    first, feedback = client.send(client.navigate, NavigateToPose.Goal(x=20.0, y=0.0))
    feedback.wait_until(lambda msgs: any(m.x > 0.0 for m in msgs), TIMEOUT_SEC)

    second, _ = client.send(client.navigate, NavigateToPose.Goal(x=0.0, y=-0.5))

    assert client.result(first).status == GoalStatus.STATUS_ABORTED
    second_response = client.result(second)
    assert second_response.status == GoalStatus.STATUS_SUCCEEDED
    assert (second_response.result.x, second_response.result.y) == (0.0, -0.5)


def test_spin_turns_by_the_angle(client: RobotClient) -> None:
    handle, feedback = client.send(client.spin, Spin.Goal(angle=-math.pi))

    response = client.result(handle)

    assert response.status == GoalStatus.STATUS_SUCCEEDED
    assert response.result.angle_travelled == pytest.approx(-math.pi)
    remaining = [abs(f.angle_remaining) for f in feedback.snapshot()]
    assert len(remaining) >= 3
    assert non_increasing(remaining)


def test_dock_drives_to_the_dock(client: RobotClient) -> None:
    client.go_to(0.5, 0.5)
    handle, feedback = client.send(client.dock, Dock.Goal(dock_id='home'))

    response = client.result(handle)

    assert response.status == GoalStatus.STATUS_SUCCEEDED
    assert response.result.docked
    distances = [f.distance_remaining for f in feedback.snapshot()]
    assert non_increasing(distances) and distances[0] > 0.0
    at_dock = client.go_to(-0.5, 0.0)
    assert (at_dock.result.x, at_dock.result.y) == (-0.5, 0.0)


def test_dock_to_an_unknown_dock_aborts(client: RobotClient) -> None:
    handle, _ = client.send(client.dock, Dock.Goal(dock_id='garage'))

    response = client.result(handle)

    assert response.status == GoalStatus.STATUS_ABORTED
    assert not response.result.docked


def test_take_photo_succeeds_with_a_new_photo_id_each_time(client: RobotClient) -> None:
    first, second = client.photo('front'), client.photo('')

    assert first.success and second.success
    assert first.photo_id and second.photo_id and first.photo_id != second.photo_id


def test_take_photo_with_the_broken_camera_fails(client: RobotClient) -> None:
    response = client.photo('broken')

    assert not response.success
    assert response.photo_id == ''
    assert 'broken' in response.message


def test_the_uplink_drops_uploads_until_as_many_as_asked_failed_in_a_row(
    client: RobotClient,
) -> None:
    assert client.upload(0).success  # whatever came before: nothing left to upload
    client.photo('front')
    client.photo('rear')

    dropped = [client.upload(2) for _ in range(2)]
    uploaded = client.upload(2)

    assert [(r.success, r.message) for r in dropped] == [
        (False, 'the link dropped the upload (1 of 2 in a row)'),
        (False, 'the link dropped the upload (2 of 2 in a row)'),
    ]
    assert (uploaded.success, uploaded.photos_uploaded) == (True, 2)
    assert not client.upload(1).success  # dropping again only after a success


def test_sigterm_ends_the_robot_cleanly_as_ctrl_c_does() -> None:
    """A service manager's SIGTERM ends the robot as Ctrl-C does (exit 0), the robot taking its
    stop signals itself rather than rclpy's handler (without which it was killed: -15)."""
    stopping = DemoProcess('sim_robot_stopped', robot_command(*ROBOT_PARAMETERS))
    try:
        stopping.wait_for_line(ROBOT_READY_LOG, START_TIMEOUT_SEC)
        stopping.signal_group(signal.SIGTERM)
        assert stopping.wait_exit(TIMEOUT_SEC) == 0, stopping.output
    finally:
        if stopping.child.wait(0) is None:
            stopping.stop()
