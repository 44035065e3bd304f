"""`Steer`: one steering bot alone in its world, tracking a commanded forward velocity
and yaw rate (legged_gym's command for a robot that cannot move sideways).

Its targets are (velocity, yaw rate) pairs (`PiecewiseConstantTwist`); the bot observes
its robot's layout (`two-wheel-steer`: the shared five, its target velocity among them,
then its yaw rate, wheel speed difference and turning command), then the yaw rate it is
asked for; it earns `TwistReward` for tracking both, and a fall ends it. The steering
tasks are rows here once calibrated (issue 52); `TASKS` holds none yet.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bbbench.robots.layout import GYRO_RANGE, ObservationField, box
from bbbench.tasks.reward import twist_outcome
from bbbench.tasks.scenario import Outcome, register_scenario
from bbbench.tasks.scenarios.solo import Solo

TARGET_YAW_RATE = ObservationField(
    "target_yaw_rate", "rad/s", -GYRO_RANGE, GYRO_RANGE, "yaw rate the task asks for, + left"
)


@register_scenario
class Steer(Solo):
    """One steering bot, started as `Solo`'s (at the origin heading along +y, leaning
    U(-initial_pitch, initial_pitch)); it observes its robot's layout, then the yaw rate
    it is asked for, earns the twist reward for tracking the commanded (velocity, yaw
    rate), and a fall ends it."""

    name = "steer"
    summary = "one steering bot tracking a commanded forward velocity and yaw rate"
    robots = ("two-wheel-steer",)
    metrics = ("velocity_error", "yaw_rate_error")
    steers = True

    def __init__(self, task) -> None:
        super().__init__(task)
        self.layout = (*self.robot.layout(), TARGET_YAW_RATE)
        self._space = box(self.layout)

    @classmethod
    def refusal(cls, task) -> str | None:
        refused = super().refusal(task)
        if refused:
            return refused
        if task.height_scan:
            return f"{task.id}: the {cls.name!r} scenario observes no height scan"
        return None

    def observe(
        self, scene: Any, states: list[Any], commands: list[float], targets: list[Any], step: int
    ) -> list[np.ndarray]:
        """The bot's robot layout through the task's sensors (its target velocity the
        first of the pair), then the target yaw rate."""
        state, (velocity, yaw_rate) = states[0], targets[0]
        values = self.robot.values(scene.reading(state, step), commands[0], velocity, state)
        yaw_rate = min(max(yaw_rate, -GYRO_RANGE), GYRO_RANGE)
        return [np.array((*values, yaw_rate), dtype=self._space.dtype)]

    def outcome(
        self, agents: list[str], states: list[Any], targets: list[Any], seed: int
    ) -> Outcome:
        """The step's reward (`twist_outcome`), whether the bot fell (which ends its
        episode), and its info."""
        reward, fell, info = twist_outcome(states[0], targets[0], self.reward)
        return Outcome((reward,), (fell,), fell, f"{agents[0]} fell" if fell else "", (info,))


# The tasks it plays come with their calibration (issue 52).
TASKS: tuple = ()
