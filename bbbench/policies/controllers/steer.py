"""The steering bot's classical law: PD balance on the forward command, and a yaw-rate
law on the turning command.

The forward command is the PD baseline's (`PDController.wheel_speed_change`, on the five
shared values, so it balances and tracks the target velocity as on the published
tasks). The turning command is fed forward from the target yaw rate and corrected by
the gyro:

    turning command = target_yaw_rate x track / (2 x wheel radius)
                      + k_yaw x (target_yaw_rate - yaw_rate)

(with the wheels rolling without slipping, a turning command d turns the bot at
2 x radius x d / track rad/s). The action is the change towards both commands: the
nearest pair of the discrete table, or the clipped changes in continuous mode.
"""

from __future__ import annotations

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
TARGET_YAW_RATE = len(_FIELDS)  # the steering scenario's field, after the robot's
_FORWARD = np.asarray(WHEEL_SPEED_CHANGES)
_TURN = np.asarray(TURN_CHANGES)


class SteerController:
    """PD balance plus a yaw-rate law, on a steering task's observation.

    Args:
        action_mode: "discrete" or "continuous" (the steering robot's modes).
        k_yaw: turning command per rad/s of yaw-rate error, (rad/s)/(rad/s).
        balance: the forward law (the PD baseline's, default gains).
    """

    def __init__(
        self, action_mode: str = "discrete", k_yaw: float = 0.5, balance: PDController | None = None
    ) -> None:
        TWO_WHEEL_STEER.check_action_mode(action_mode)
        self.action_mode = action_mode
        self.k_yaw = k_yaw
        self.balance = balance or PDController("continuous")
        self.feed_forward = TRACK / (2 * TWO_WHEEL_STEER.wheel_radius)

    def changes(self, observation: np.ndarray) -> tuple[float, float]:
        """The changes of the forward and turning commands (rad/s) the law wants."""
        forward = self.balance.wheel_speed_change(observation)
        target = float(observation[TARGET_YAW_RATE])
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
