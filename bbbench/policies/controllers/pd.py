"""The PD baseline: a hand-written controller for every single-bot task.

It reads only the shared observation layout, so it runs on any task:

    desired command = target_velocity / wheel_radius
                      + kp * pitch + kd * pitch_rate + kv * (velocity - target_velocity)

where velocity = wheel_radius * (wheel_speed + pitch_rate) is the encoders'
estimate of forward velocity (wheel speed is measured relative to the torso).
Leaning forward, it drives forward to get the wheels back under the torso;
the velocity term stops it drifting away from its target. The first term
feeds the target forward: balanced at a steady speed, the command equals the
wheel speed, and without it that balance would settle at a speed of
kv / (kv - 1 / wheel_radius) times the target (2x with these gains). The action is the
change towards the desired command: the nearest entry of the discrete table,
or the clipped change in continuous mode.
"""

from __future__ import annotations

import numpy as np

from bbbench.robots.layout import INDEX
from bbbench.robots.twowheel import (
    ACTION_MODES,
    MAX_WHEEL_SPEED_CHANGE,
    TWO_WHEEL,
    WHEEL_SPEED_CHANGES,
)

_CHANGES = np.asarray(WHEEL_SPEED_CHANGES)


class PDController:
    """Balance by proportional-derivative feedback on pitch, plus velocity feedback.

    Args:
        action_mode: the env's action mode, "discrete" or "continuous".
        kp: command per rad of pitch, (rad/s)/rad.
        kd: command per rad/s of pitch rate, (rad/s)/(rad/s).
        kv: command per m/s of velocity error, (rad/s)/(m/s).
        hold_velocity: None (default) tracks the observed target velocity; a number, in
            m/s, is held instead whatever the task asks (0.0: the `stand` policy, which
            stays up and does not drive).
        wheel_radius: m, for the encoders' estimate of velocity (the two-wheel bot's).

    The default gains keep FlatBalance-v0 up for the full episode on every seed
    tested (tests/test_baselines.py).
    """

    def __init__(
        self,
        action_mode: str = "discrete",
        kp: float = 40.0,
        kd: float = 6.0,
        kv: float = 20.0,
        hold_velocity: float | None = None,
        wheel_radius: float = TWO_WHEEL.wheel_radius,
    ) -> None:
        if action_mode not in ACTION_MODES:
            raise ValueError(f"action_mode must be one of {ACTION_MODES}, got {action_mode!r}")
        self.action_mode = action_mode
        self.kp, self.kd, self.kv = kp, kd, kv
        self.hold_velocity = hold_velocity
        self.wheel_radius = wheel_radius

    def wheel_speed_change(
        self, observation: np.ndarray, balance_pitch: float = 0.0, target: float | None = None
    ) -> float:
        """The change of wheel command (rad/s) the controller wants. `balance_pitch` (rad):
        the pitch at which the robot's centre of mass is over its axle (0 for the
        two-wheel bot; the wheel-legged robot's depends on its legs). `target` (m/s), if
        given, is tracked instead of the observed target (and of `hold_velocity`)."""
        pitch = float(observation[INDEX["pitch"]]) - balance_pitch
        pitch_rate = float(observation[INDEX["pitch_rate"]])
        velocity = self.wheel_radius * (float(observation[INDEX["wheel_speed"]]) + pitch_rate)
        if target is None:
            target = (
                float(observation[INDEX["target_velocity"]])
                if self.hold_velocity is None
                else self.hold_velocity
            )
        desired = (
            target / self.wheel_radius  # fed forward
            + self.kp * pitch
            + self.kd * pitch_rate
            + self.kv * (velocity - target)
        )
        return desired - float(observation[INDEX["wheel_command"]])

    def __call__(self, observation: np.ndarray) -> int | np.ndarray:
        """The action for one observation."""
        change = self.wheel_speed_change(observation)
        if self.action_mode == "discrete":
            return int(np.argmin(np.abs(_CHANGES - change)))
        scaled = np.clip(change / MAX_WHEEL_SPEED_CHANGE, -1.0, 1.0)
        return np.array([scaled], dtype=np.float32)

    def predict(
        self,
        observation: np.ndarray,
        state: object = None,
        episode_start: object = None,
        deterministic: bool = True,
    ) -> tuple[int | np.ndarray, None]:
        """stable-baselines3's `predict` signature; a 2-D batch gives a batch of actions."""
        observation = np.asarray(observation)
        if observation.ndim == 2:
            return np.stack([np.asarray(self(row)) for row in observation]), None
        return self(observation), None
