"""How the simulated robot moves on a plane, free of ROS: poses and fixed-time steps."""

import math
from dataclasses import dataclass, replace
from typing import Protocol

# Below these the robot counts as arrived; steps snap to the target, so they only absorb
# floating-point rounding.
POSITION_TOLERANCE = 1e-9
HEADING_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Pose:
    """A pose on the map plane: metres, and a heading in radians within [-pi, pi]."""

    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0

    def distance_to(self, other: 'Pose') -> float:
        return math.hypot(other.x - self.x, other.y - self.y)

    def heading_to(self, other: 'Pose') -> float:
        return math.atan2(other.y - self.y, other.x - self.x)

    def __str__(self) -> str:
        return f'({self.x:.2f}, {self.y:.2f}, {self.theta:.2f})'


@dataclass(frozen=True)
class Speeds:
    """Top speeds of the robot: m/s and rad/s."""

    linear: float
    angular: float


def normalize_angle(angle: float) -> float:
    """The same direction as `angle`, within [-pi, pi]."""
    return math.atan2(math.sin(angle), math.cos(angle))


def clamp(value: float, limit: float) -> float:
    """`value` limited to [-limit, limit]."""
    return max(-limit, min(limit, value))


def turn_towards(theta: float, target: float, max_step: float) -> float:
    """The heading after turning from `theta` towards `target` by at most `max_step`."""
    error = normalize_angle(target - theta)
    if abs(error) <= max_step:
        return normalize_angle(target)
    return normalize_angle(theta + clamp(error, max_step))


class Motion(Protocol):
    """A motion of the robot, advanced by fixed time steps until it is finished."""

    def step(self, pose: Pose, dt: float) -> Pose: ...

    def finished(self, pose: Pose) -> bool: ...


class DriveToPose:
    """Turn on the spot to face the goal, drive straight to it, then turn to its heading."""

    def __init__(self, goal: Pose, speeds: Speeds) -> None:
        self.goal = replace(goal, theta=normalize_angle(goal.theta))
        self.speeds = speeds

    def step(self, pose: Pose, dt: float) -> Pose:
        distance = pose.distance_to(self.goal)
        if distance <= POSITION_TOLERANCE:
            return replace(
                self.goal, theta=turn_towards(pose.theta, self.goal.theta, self._turn(dt))
            )
        heading = pose.heading_to(self.goal)
        if abs(normalize_angle(heading - pose.theta)) > HEADING_TOLERANCE:
            return replace(pose, theta=turn_towards(pose.theta, heading, self._turn(dt)))
        travel = self.speeds.linear * dt
        if travel >= distance:
            return replace(self.goal, theta=heading)
        return Pose(
            pose.x + travel * math.cos(heading), pose.y + travel * math.sin(heading), heading
        )

    def finished(self, pose: Pose) -> bool:
        return (
            pose.distance_to(self.goal) <= POSITION_TOLERANCE
            and abs(normalize_angle(self.goal.theta - pose.theta)) <= HEADING_TOLERANCE
        )

    def distance_remaining(self, pose: Pose) -> float:
        return pose.distance_to(self.goal)

    def _turn(self, dt: float) -> float:
        return self.speeds.angular * dt


class SpinBy:
    """Turn on the spot by a signed angle, which may be more than a full turn."""

    def __init__(self, angle: float, speeds: Speeds) -> None:
        self.angle = angle
        self.travelled = 0.0
        self.speeds = speeds

    @property
    def remaining(self) -> float:
        return self.angle - self.travelled

    def step(self, pose: Pose, dt: float) -> Pose:
        turn = clamp(self.remaining, self.speeds.angular * dt)
        self.travelled += turn
        return replace(pose, theta=normalize_angle(pose.theta + turn))

    def finished(self, pose: Pose) -> bool:
        return abs(self.remaining) <= HEADING_TOLERANCE
