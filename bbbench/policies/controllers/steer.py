"""The steering bot's classical law: PD balance on the forward command, and a yaw-rate
law on the turning command, towards a (velocity, yaw rate) its task's guide makes from
the observation.

A guide reads a task's own fields: `commanded` the (velocity, yaw rate) a
`SteerTracking` task asks for; `toward_goal` one that heads for a waypoint:

    yaw rate = k_heading x sin(bearing), or +-k_heading when the goal is behind
    velocity = target speed x max(cos(bearing), 0)

(clipped to +-`MAX_GUIDED_YAW_RATE`): it turns towards its goal, in place when the goal
is behind, and drives as fast as it faces it.

The forward command is the PD baseline's (`PDController.wheel_speed_change`, on the five
shared values, so it balances and tracks the guide's velocity as on the published
tasks). The turning command is fed forward from the target yaw rate and corrected by
the gyro:

    turning command = target_yaw_rate x track / (2 x wheel radius)
                      + k_yaw x (target_yaw_rate - yaw_rate)

(with the wheels rolling without slipping, a turning command d turns the bot at
2 x radius x d / track rad/s). The action is the change towards both commands: the
nearest pair of the discrete table, or the clipped changes in continuous mode.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from bbbench.policies.controllers.pd import PDController
from bbbench.robots.steering import (
    MAX_TURN_CHANGE,
    OBSERVATION_LAYOUT,
    TURN_CHANGES,
    TWO_WHEEL_STEER,
)
from bbbench.robots.twowheel import MAX_WHEEL_SPEED_CHANGE, WHEEL_SPEED_CHANGES

TRACK = 0.24  # m between the wheels (balancebot.urdf)
_FIELDS = [field.name for field in OBSERVATION_LAYOUT]
YAW_RATE, TURN_COMMAND = _FIELDS.index("yaw_rate"), _FIELDS.index("turn_command")
TARGET_VELOCITY = _FIELDS.index("target_velocity")
TARGET_YAW_RATE = len(_FIELDS)  # the steering scenario's field, after the robot's
GOAL_COS, GOAL_SIN = len(_FIELDS) + 1, len(_FIELDS) + 2  # the waypoints scenario's
K_HEADING = 3.0  # (rad/s) of yaw rate per unit of the goal bearing's sine
MAX_GUIDED_YAW_RATE = 3.0  # rad/s
_FORWARD = np.asarray(WHEEL_SPEED_CHANGES)
_TURN = np.asarray(TURN_CHANGES)

Guide = Callable[[np.ndarray], tuple[float, float]]


def commanded(observation: np.ndarray) -> tuple[float, float]:
    """The (velocity, yaw rate) a twist-commanded task asks for (the `steer` scenario)."""
    return float(observation[TARGET_VELOCITY]), float(observation[TARGET_YAW_RATE])


def toward_goal(observation: np.ndarray) -> tuple[float, float]:
    """A (velocity, yaw rate) that heads for the goal (the `waypoints` scenario)."""
    speed = float(observation[TARGET_VELOCITY])
    cos, sin = float(observation[GOAL_COS]), float(observation[GOAL_SIN])
    if cos > 0.0:
        yaw_rate = min(max(K_HEADING * sin, -MAX_GUIDED_YAW_RATE), MAX_GUIDED_YAW_RATE)
        return speed * cos, yaw_rate
    return 0.0, MAX_GUIDED_YAW_RATE if sin >= 0.0 else -MAX_GUIDED_YAW_RATE


def heading_for(forward: float, right: float, speed: float) -> tuple[float, float]:
    """A (velocity, yaw rate) that heads along the body-frame vector (forward, right) m/s,
    as `toward_goal` heads for a goal: turning in place when it points behind."""
    size = math.sqrt(forward * forward + right * right)  # correctly rounded, as IEEE asks
    if size == 0.0:
        return 0.0, 0.0
    cos, sin = forward / size, -right / size
    if cos > 0.0:
        yaw_rate = min(max(K_HEADING * sin, -MAX_GUIDED_YAW_RATE), MAX_GUIDED_YAW_RATE)
        return min(size, speed) * cos, yaw_rate
    return 0.0, MAX_GUIDED_YAW_RATE if sin >= 0.0 else -MAX_GUIDED_YAW_RATE


class Avoiding:
    """A guide towards the goal that keeps clear of the neighbours the observation holds
    (the `swap` scenario's layout: the goal after the robot's values, then slots of
    right, forward, right velocity, forward velocity):

        wanted = speed x unit(goal)
                 + sum over neighbours within `radius` m of
                   speed x w x (push x unit(away from it) + keep_right x [it is ahead])

    with w = 1 - distance / radius; `keep_right` steers every bot to its right of the
    one ahead, so that bots meeting head on pass each other on the same side (the rule
    of the road). The bot heads along `wanted` (`heading_for`)."""

    def __init__(
        self,
        first_slot: int,
        slots: int,
        radius: float = 1.2,
        push: float = 1.0,
        keep_right: float = 1.0,
        lane: float = 0.8,
    ) -> None:
        self.first_slot, self.slots = first_slot, slots
        self.radius, self.push, self.keep_right, self.lane = radius, push, keep_right, lane

    def __call__(self, observation: np.ndarray) -> tuple[float, float]:
        speed = float(observation[TARGET_VELOCITY])
        cos, sin = float(observation[GOAL_COS]), float(observation[GOAL_SIN])
        return self.around(observation, speed * cos, -speed * sin, speed)

    def around(
        self, observation: np.ndarray, forward: float, right: float, speed: float
    ) -> tuple[float, float]:
        """The (velocity, yaw rate) along the body-frame velocity (forward, right) m/s a
        guide wants, at up to `speed`, pushed clear of the neighbours."""
        radius = self.radius
        for k in range(self.slots):
            at = self.first_slot + 4 * k
            r, f = float(observation[at]), float(observation[at + 1])
            distance = math.sqrt(r * r + f * f)
            if distance == 0.0 or distance >= radius:
                continue  # an empty slot, or too far to matter
            weight = speed * (1.0 - distance / radius)
            forward -= weight * self.push * f / distance
            right -= weight * self.push * r / distance
            if f > 0.0 and abs(r) < self.lane:
                right += weight * self.keep_right
        return heading_for(forward, right, speed)


# The guide for what a scenario says a steering bot heads for (`Scenario.heads_for`).
GUIDES: dict[str, Guide] = {"the command": commanded, "the goal": toward_goal}


class SteerController:
    """PD balance plus a yaw-rate law, on a steering task's observation.

    Args:
        action_mode: "discrete" or "continuous" (the steering robot's modes).
        k_yaw: turning command per rad/s of yaw-rate error, (rad/s)/(rad/s).
        balance: the forward law (the PD baseline's, default gains).
        guide: the (velocity, yaw rate) to track, from the observation (`GUIDES`); the
            commanded pair by default.
    """

    def __init__(
        self,
        action_mode: str = "discrete",
        k_yaw: float = 0.5,
        balance: PDController | None = None,
        guide: Guide = commanded,
    ) -> None:
        TWO_WHEEL_STEER.check_action_mode(action_mode)
        self.action_mode = action_mode
        self.k_yaw = k_yaw
        self.balance = balance or PDController("continuous")
        self.guide = guide
        self.feed_forward = TRACK / (2 * TWO_WHEEL_STEER.wheel_radius)

    @classmethod
    def for_scenario(cls, scenario: type, action_mode: str = "discrete") -> SteerController:
        """The law with the guide for what the steering `scenario` (a class) heads for."""
        return cls(action_mode, guide=GUIDES[scenario.heads_for])

    def changes(self, observation: np.ndarray) -> tuple[float, float]:
        """The changes of the forward and turning commands (rad/s) the law wants."""
        velocity, target = self.guide(observation)
        forward = self.balance.wheel_speed_change(observation, target=velocity)
        wanted = self.feed_forward * target + self.k_yaw * (target - float(observation[YAW_RATE]))
        return forward, wanted - float(observation[TURN_COMMAND])

    def __call__(self, observation: np.ndarray) -> int | np.ndarray:
        """The action for one observation."""
        forward, turn = self.changes(observation)
        if self.action_mode == "discrete":
            f = int(np.argmin(np.abs(_FORWARD - forward)))
            t = int(np.argmin(np.abs(_TURN - turn)))
            return f * len(TURN_CHANGES) + t
        return np.array(
            [
                np.clip(forward / MAX_WHEEL_SPEED_CHANGE, -1.0, 1.0),
                np.clip(turn / MAX_TURN_CHANGE, -1.0, 1.0),
            ],
            dtype=np.float32,
        )
