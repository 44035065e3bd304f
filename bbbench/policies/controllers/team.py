"""The classical team controller of the column tasks (`bbbench.tasks.scenarios.column`):
PD on every bot, each on a target it makes from what it observes of its team.

- The front bot (no bot ahead) observes the team's target. It asks PD for that target,
  but never more than `accel` x `horizon` m/s away from its own velocity: the target
  it follows changes no faster than the bot can, so the team is not thrown.
- A follower observes 0 in the target slot. It asks PD for the velocity of the bot
  ahead (its own velocity plus the one it observes ahead) plus `pull_gain` times the
  coupling's pull forward: the hinges' force along the beam (N), or the stretch of the
  tether ahead (m).

Its own velocity is PD's estimate, wheel radius x (wheel speed + pitch rate). The law is
stateless: one observation in, one action out, so it plays any episode in any order.

On a column of steering bots (ConvoyTurns), `SteeringTeam` adds the turning: the front
bot asks the steering law for the yaw rate it is commanded, and a follower for
`K_HEADING` x the sine of the bearing of the bot ahead, so that it drives after it.

On a mixed team (MixedBeamCarry), `LeggedTeam` plays a wheel-legged robot: the same law
makes its target, and the wheel-legged robot's controller (`LeggedController`) tracks it
on its wheels, its legs a little longer than standing (`MIXED_LEG_LENGTH`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bbbench.policies.controllers.legged import LeggedController
from bbbench.policies.controllers.pd import PDController
from bbbench.policies.controllers.steer import heading_for
from bbbench.robots.layout import INDEX, ObservationField

# The gain the law gives the coupling's pull forward, by the unit it is read in.
PULL_GAINS = {"N": 0.2, "m": 3.0}  # (m/s)/N (a beam's hinges), (m/s)/m (a tether's stretch)
# m, hip to axle: a wheel-legged robot's legs in a mixed team, a little longer than
# standing (0.248 m), so that the front robot carries a share of the beam on its wheels.
# Chosen on the first 20 validation seeds of each mixed task, the best mean over both
# (`python scripts/calibrate_mixed.py --legs 0.24 0.25 0.26 0.27 0.28`): mean team return
# 36.1, 66.3, 72.7, 71.3 and 58.2 on the flat, 37.7, 61.6, 65.1, 68.5 and 54.3 on the
# hills. Shorter legs hang the robot from the beam, its wheels off the ground (the front
# one can no longer lead); longer ones lift the beam off the two-wheel bots.
MIXED_LEG_LENGTH = 0.27


class TeamController:
    """The team law over `PDController`, for one bot of a column task.

    Args:
        layout: the task's observation fields, in order (the scenario's `layout`).
        pull: the field that reads the coupling's pull forward (the scenario's
            `pull_forward`).
        action_mode: "discrete" or "continuous".
        accel: m/s^2, how fast the front bot's own target may pull away from its velocity.
        horizon: s, over which `accel` applies.
        pull_gain: (m/s) per unit of the pull; None: `PULL_GAINS`'s for its unit.
    """

    def __init__(
        self,
        layout: Sequence[ObservationField],
        pull: str,
        action_mode: str = "discrete",
        accel: float = 2.0,
        horizon: float = 0.25,
        pull_gain: float | None = None,
    ) -> None:
        self.pd = PDController(action_mode)
        index = {field.name: i for i, field in enumerate(layout)}
        missing = [
            name for name in ("ahead_present", "ahead_forward_velocity", pull) if name not in index
        ]
        if missing:
            raise ValueError(
                "the team controller plays the column tasks (a coupling's pull, neighbours "
                f"ahead and behind); this layout lacks {missing}"
            )
        self._ahead = index["ahead_present"]
        self._ahead_velocity = index["ahead_forward_velocity"]
        self._pull = index[pull]
        unit = layout[self._pull].unit
        if pull_gain is None and unit not in PULL_GAINS:
            raise ValueError(f"no gain for a pull read in {unit!r}: give pull_gain")
        self.pull_gain = PULL_GAINS[unit] if pull_gain is None else pull_gain
        self.reach = accel * horizon  # m/s

    @classmethod
    def for_scenario(cls, scenario, action_mode: str = "discrete", **gains) -> TeamController:
        """The law for a column scenario's bots: its layout and its pull."""
        return cls(list(scenario.layout), scenario.pull_forward, action_mode, **gains)

    def target(self, observation: np.ndarray) -> float:
        """The velocity (m/s) this bot asks PD for."""
        velocity = self.pd.wheel_radius * (
            float(observation[INDEX["wheel_speed"]]) + float(observation[INDEX["pitch_rate"]])
        )
        if observation[self._ahead] == 0.0:  # the front bot
            target = float(observation[INDEX["target_velocity"]])
            return min(max(target, velocity - self.reach), velocity + self.reach)
        ahead = velocity + float(observation[self._ahead_velocity])
        return ahead + self.pull_gain * float(observation[self._pull])

    def __call__(self, observation: np.ndarray) -> int | np.ndarray:
        """The action for one bot's observation."""
        shared = np.array(observation[: len(INDEX)], dtype=np.float32)
        shared[INDEX["target_velocity"]] = self.target(observation)
        return self.pd(shared)


class LeggedTeam:
    """The team law for a wheel-legged robot of a mixed team: `TeamController`'s target
    (from its own layout), tracked by `LeggedController` with its legs at `leg_length`."""

    def __init__(self, layout: Sequence[ObservationField], pull: str, leg_length: float) -> None:
        self.team = TeamController(layout, pull, "continuous")
        self.legged = LeggedController(leg_length=leg_length)

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        guided = np.array(observation, dtype=np.float32)
        guided[INDEX["target_velocity"]] = self.team.target(observation)
        return self.legged(guided)


class SteeringTeam:
    """The team law's guide for a column of steering bots: the (velocity, yaw rate) the
    steering law (`SteerController`) tracks. The velocity is `TeamController.target`'s;
    the yaw rate the commanded one for the front bot, and for a follower one that turns
    it towards the bot ahead (`heading_for` the offset of that bot)."""

    def __init__(self, scenario) -> None:
        self.team = TeamController.for_scenario(scenario, "continuous")
        index = {field.name: i for i, field in enumerate(scenario.layout)}
        self._ahead = index["ahead_present"]
        self._right, self._forward = index["ahead_right"], index["ahead_forward"]
        self._yaw_rate = index["target_yaw_rate"]

    def __call__(self, observation: np.ndarray) -> tuple[float, float]:
        velocity = self.team.target(observation)
        if observation[self._ahead] == 0.0:  # the front bot
            return velocity, float(observation[self._yaw_rate])
        right, forward = float(observation[self._right]), float(observation[self._forward])
        if forward < 0.0:  # the bot ahead is behind it (reversing): back after it
            forward, right = -forward, -right
        return velocity, heading_for(forward, right, abs(velocity))[1]
