"""The simulated robot's motion, without ROS."""

import itertools
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from task_manager_demo.motion import (
    POSITION_TOLERANCE,
    DriveToPose,
    Motion,
    Pose,
    Speeds,
    SpinBy,
    normalize_angle,
    turn_towards,
)

DT = 0.1
SPEEDS = Speeds(linear=0.5, angular=1.0)
coordinates = st.floats(min_value=-20.0, max_value=20.0, allow_nan=False)
angles = st.floats(min_value=-10.0, max_value=10.0, allow_nan=False)


def run(motion: Motion, pose: Pose, max_steps: int = 10_000) -> list[Pose]:
    """The poses after each step until the motion is finished."""
    poses = [pose]
    while not motion.finished(poses[-1]):
        assert len(poses) <= max_steps, 'motion did not finish'
        poses.append(motion.step(poses[-1], DT))
    return poses


def steps_needed(distance: float, turns: float) -> int:
    """An upper bound of the steps of a drive: both turns, the straight line, rounding."""
    return math.ceil(distance / (SPEEDS.linear * DT) + turns / (SPEEDS.angular * DT)) + 3


@pytest.mark.parametrize(
    ('angle', 'expected'),
    [
        (0.0, 0.0),
        (math.pi / 2, math.pi / 2),
        (3 * math.pi, math.pi),
        (-5 * math.pi / 2, -math.pi / 2),
    ],
)
def test_normalize_angle(angle: float, expected: float) -> None:
    assert normalize_angle(angle) == pytest.approx(expected)


def test_turn_towards_takes_the_short_way_and_snaps_to_the_target() -> None:
    assert turn_towards(3.0, -3.0, 0.1) == pytest.approx(3.1)
    assert turn_towards(0.0, 0.05, 0.1) == 0.05
    assert turn_towards(0.0, -1.0, 0.1) == pytest.approx(-0.1)


def test_drive_turns_on_the_spot_then_drives_straight_then_turns_to_the_goal_heading() -> None:
    goal = Pose(0.0, 1.0, math.pi)

    poses = run(DriveToPose(goal, SPEEDS), Pose())

    facing_goal = next(i for i, p in enumerate(poses) if p.theta == pytest.approx(math.pi / 2))
    arrived = next(i for i, p in enumerate(poses) if p.distance_to(goal) == 0.0)
    assert all(p.x == 0.0 and p.y == 0.0 for p in poses[: facing_goal + 1])
    assert all(p.theta == pytest.approx(math.pi / 2) for p in poses[facing_goal : arrived + 1])
    assert poses[-1] == goal
    assert len(poses) - 1 == math.ceil(0.5 * math.pi / 0.1) * 2 + 20


@given(coordinates, coordinates, angles, coordinates, coordinates, angles)
def test_drive_reaches_any_goal_within_its_speed_limits(
    x: float, y: float, theta: float, goal_x: float, goal_y: float, goal_theta: float
) -> None:
    start, goal = Pose(x, y, normalize_angle(theta)), Pose(goal_x, goal_y, goal_theta)
    motion = DriveToPose(goal, SPEEDS)

    poses = run(motion, start)

    distances = [motion.distance_remaining(p) for p in poses]
    assert distances == sorted(distances, reverse=True)
    assert poses[-1].distance_to(goal) <= POSITION_TOLERANCE
    assert poses[-1].theta == pytest.approx(normalize_angle(goal_theta), abs=1e-9)
    assert len(poses) - 1 <= steps_needed(start.distance_to(goal), 2 * math.pi)
    for before, after in itertools.pairwise(poses):
        assert before.distance_to(after) <= SPEEDS.linear * DT + 1e-9
        assert abs(normalize_angle(after.theta - before.theta)) <= SPEEDS.angular * DT + 1e-9


@given(angles)
def test_spin_turns_by_the_signed_angle_even_past_a_full_turn(angle: float) -> None:
    motion = SpinBy(angle, SPEEDS)

    poses = run(motion, Pose(1.0, 2.0, 0.0))

    assert motion.travelled == pytest.approx(angle, abs=1e-9)
    assert poses[-1].theta == pytest.approx(normalize_angle(angle), abs=1e-6)
    assert all((p.x, p.y) == (1.0, 2.0) for p in poses)
    assert len(poses) - 1 <= math.ceil(abs(angle) / (SPEEDS.angular * DT)) + 1


def test_spin_reports_what_remains_with_its_sign() -> None:
    motion = SpinBy(-1.0, SPEEDS)

    motion.step(Pose(), DT)

    assert motion.remaining == pytest.approx(-0.9)
    assert motion.travelled == pytest.approx(-0.1)
