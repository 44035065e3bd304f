"""The wheel-legged robot's classical controller: balance through the wheels, as the PD
baseline does, and ride low on the legs, which damp the torso's roll.

Wheels. Both get the PD baseline's change of command (`PDController`, the same gains),
on the pitch measured from the *balance pitch*: the torso's pitch at which the whole
robot's centre of mass is over the axle, computed from the observed leg angles and the
masses and lengths of the URDF (`balance_pitch`). With the legs forward of the torso's
axis, the robot balances leaning back a little (-0.03 rad standing); without the
correction the PD law would settle there at a steady drift of about 0.1 m/s.

Legs. The legs ride low and damp the torso's roll: each is held at a length (hip to
axle) of `leg_length`, 0.15 m by default (0.248 m standing, 0.109 m at the knees' end),
plus or minus half a correction

    dh = k_roll * roll + k_roll_rate * roll_rate        (m; roll > 0 leans right)
    right length = leg_length + dh / 2,  left length = leg_length - dh / 2

with k_roll = 0 and k_roll_rate = 0.1 m/(rad/s): the side that is sinking stretches its
leg. A length h is the pose hip = q, knee = -2 q with q = acos(h / (2 L)), which keeps
the wheel under the hip; lengths are limited to what the joints reach.

First measured on the evaluation seeds (episodes finished, mean return), each setting
changed alone from the others' (below); made again on the validation seeds, where no
other setting is clearly better and these stand (`python scripts/choices.py --evaluate
legged-controller`, baselines/choices/legged-controller.json):
- Riding low: a lower centre of mass takes the ground's kicks with a shorter lever. On
  Obstacles-v2's course at 0.6, 50 episodes (k_roll 0.5, k_roll_rate 0.05): 0.18 m, 24
  and 52.0; 0.15 m, 43 and 59.3; 0.12 m, 39 and 46.3. On LeggedBumps-v0's hills at 0.75,
  100 episodes (k_roll 0, k_roll_rate 0.05): 0.15 m, 65 and 46.2; 0.12 m, 58 and 39.7.
- Damping roll, not levelling it: at 0.15 m and k_roll 0, k_roll_rate 0, 0.05, 0.1 and
  0.2 finished 22, 65, 72 and 62 of 100 on the hills at 0.75 (mean returns 30.1, 46.2,
  52.6, 55.3), and 45, 47 and 41 on the LeggedObstacles-v0 course (0.05-0.2; 34.2, 39.3,
  36.1). Levelling the roll angle itself cost episodes: at 0.12 m on that course, k_roll
  0, 0.5 and 1.0 finished 57, 47 and 51 (34.7, 34.5, 34.4).
"""

from __future__ import annotations

import math

import numpy as np

from bbbench.policies.controllers.pd import PDController
from bbbench.portable import total
from bbbench.robots.wheel_legged import (
    LEG_JOINT_NAMES,
    LEGGED_MODEL,
    MAX_WHEEL_SPEED_CHANGE,
    OBSERVATION_LAYOUT,
    LeggedModel,
)

_ANGLES = [
    [field.name for field in OBSERVATION_LAYOUT].index(f"{name}_angle") for name in LEG_JOINT_NAMES
]
_ROLL = [field.name for field in OBSERVATION_LAYOUT].index("roll")
_ROLL_RATE = _ROLL + 1


def balance_pitch(model: LeggedModel, hip: float, knee: float) -> float:
    """The torso pitch (rad) that puts the robot's centre of mass over its axle, both legs
    at (hip, knee): links as point masses at their centres, in the torso's sagittal plane."""
    thigh, shin = model.thigh_length, model.shin_length
    link_mass = (model.mass - model.torso_mass - 2 * model.wheel_mass) / 4
    # (forward, up) of each part relative to the hip, along the torso's axes.
    knee_at = (thigh * math.sin(hip), -thigh * math.cos(hip))
    axle = (knee_at[0] + shin * math.sin(hip + knee), knee_at[1] - shin * math.cos(hip + knee))
    parts = [
        (model.torso_mass, (0.0, model.hip_below_centre)),
        (2 * link_mass, (0.5 * knee_at[0], 0.5 * knee_at[1])),
        (2 * link_mass, (0.5 * (knee_at[0] + axle[0]), 0.5 * (knee_at[1] + axle[1]))),
        (2 * model.wheel_mass, axle),
    ]
    mass = total(m for m, _ in parts)
    ahead = total(m * p[0] for m, p in parts) / mass - axle[0]
    above = total(m * p[1] for m, p in parts) / mass - axle[1]
    # Leaning forward by p moves a point (ahead, above) of the torso's frame forward by
    # ahead cos p + above sin p: zero at p = -atan(ahead / above).
    return -math.atan2(ahead, above)


class LeggedController:
    """Balance the wheel-legged robot through its wheels, riding low on its legs and
    damping its roll with them.

    Args:
        kp, kd, kv: the wheels' PD gains (`PDController`'s, and its defaults).
        k_roll: leg length difference per rad of roll, m/rad.
        leg_length: each leg's length (hip to axle) with the torso level, m.
        k_roll_rate: leg length difference per rad/s of roll rate, m/(rad/s).
        hold_velocity: as `PDController`'s (None tracks the task's target).
    """

    def __init__(
        self,
        kp: float = 40.0,
        kd: float = 6.0,
        kv: float = 20.0,
        k_roll: float = 0.0,
        k_roll_rate: float = 0.1,
        hold_velocity: float | None = None,
        leg_length: float = 0.15,
        model: LeggedModel = LEGGED_MODEL,
    ) -> None:
        self.wheels = PDController("continuous", kp, kd, kv, hold_velocity, model.wheel_radius)
        self.k_roll, self.k_roll_rate = k_roll, k_roll_rate
        self.model = model
        knee = model.legs[1]
        self._reach = model.thigh_length + model.shin_length  # the straight leg's length
        self._length = leg_length
        # The lengths the joints reach with knee = -2 hip (hip from 0 to the knee's end / 2).
        self._shortest = model.axle_below_hip(-knee.lower / 2, knee.lower)

    def leg_actions(self, roll: float, roll_rate: float) -> list[float]:
        """The four leg values of the action: each leg's pose for its length."""
        difference = self.k_roll * roll + self.k_roll_rate * roll_rate
        values = []
        for length in (self._length - difference / 2, self._length + difference / 2):
            length = min(self._reach, max(self._shortest, length))
            q = math.acos(length / self._reach)
            for leg, angle in zip(self.model.legs[:2], (q, -2 * q), strict=True):
                values.append((angle - leg.centre) / leg.half_range)
        return values  # left hip, left knee, right hip, right knee

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        """The action for one observation."""
        hip = 0.5 * (float(observation[_ANGLES[0]]) + float(observation[_ANGLES[2]]))
        knee = 0.5 * (float(observation[_ANGLES[1]]) + float(observation[_ANGLES[3]]))
        change = self.wheels.wheel_speed_change(observation, balance_pitch(self.model, hip, knee))
        wheel = min(1.0, max(-1.0, change / MAX_WHEEL_SPEED_CHANGE))
        legs = self.leg_actions(float(observation[_ROLL]), float(observation[_ROLL_RATE]))
        return np.array([*legs, wheel, wheel], dtype=np.float32)
