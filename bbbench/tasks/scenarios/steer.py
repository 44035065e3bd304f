"""`Steer`: one steering bot alone in its world, tracking a commanded forward velocity
and yaw rate (legged_gym's command for a robot that cannot move sideways).

Its targets are (velocity, yaw rate) pairs (`PiecewiseConstantTwist`); the bot observes
its robot's layout (`two-wheel-steer`: the shared five, its target velocity among them,
then its yaw rate, wheel speed difference and turning command), then the yaw rate it is
asked for; it earns `TwistReward` for tracking both, and a fall ends it. Its task,
`SteerTracking-v0`, is the row at the end.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bbbench.robots.layout import GYRO_RANGE, ObservationField
from bbbench.robots.steering import steer_observation
from bbbench.tasks.commands import PiecewiseConstantTwist
from bbbench.tasks.reward import TwistReward, twist_outcome
from bbbench.tasks.scenario import Outcome, register_scenario
from bbbench.tasks.scenarios.solo import Solo
from bbbench.tasks.spec import TaskSpec

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
    scans_ground = False
    heads_for = "the command"

    def __init__(self, task) -> None:
        super().__init__(task)
        self.layout = (*self.robot.layout(), TARGET_YAW_RATE)

    def observe(
        self, scene: Any, states: list[Any], commands: list[float], targets: list[Any], step: int
    ) -> list[np.ndarray]:
        """The bot's robot layout through the task's sensors (its target velocity the
        first of the pair), then the target yaw rate."""
        state, (velocity, yaw_rate) = states[0], targets[0]
        yaw_rate = min(max(yaw_rate, -GYRO_RANGE), GYRO_RANGE)
        if scene.perfect_sensors:  # the reading is the state's (the hot path)
            reading = (state.pitch, state.pitch_rate, state.wheel_speed)
        else:
            reading = scene.reading(state, step)
        return [steer_observation(reading, commands[0], velocity, state, yaw_rate)]

    def outcome(
        self, agents: list[str], states: list[Any], targets: list[Any], seed: int
    ) -> Outcome:
        """The step's reward (`twist_outcome`), whether the bot fell (which ends its
        episode), and its info."""
        reward, fell, info = twist_outcome(states[0], targets[0], self.reward)
        return Outcome((reward,), (fell,), fell, f"{agents[0]} fell" if fell else "", (info,))


# The robot's whole envelope: its turning command's limit makes about 5 rad/s, and 2 m/s
# is within its top speed. Calibration: docs/tasks.md, "The steering tasks".
_ENVELOPE = PiecewiseConstantTwist(low=-2.0, high=2.0, yaw_low=-5.0, yaw_high=5.0, hold=(2.0, 5.0))

TASKS = (
    TaskSpec(
        id="bbbench/SteerTracking-v0",
        summary="track a commanded velocity (+-2 m/s) and yaw rate (+-5 rad/s) on flat ground",
        description="""\
legged_gym's command for a robot that cannot move sideways: a forward velocity drawn from
[-2, 2] m/s and a yaw rate from [-5, 5] rad/s (+ turning left), the pair held for a
duration drawn from 2-5 s, then the next, all from the episode's seed. The pairs span the
robot's whole envelope: 5 rad/s is about its turning limit, and a fast turn at speed
throws the bot sideways (its centripetal acceleration, velocity x yaw rate, reaches
10 m/s^2), so a policy that tracks every pair falls on some, and one that knows its
limits gives up a little tracking to stay up. Flat ground; sensors are perfect. The bot
observes the robot's eight values (the target velocity is observation 4), then the
target yaw rate.

The reward (`TwistReward`), each step in [0, 0.1]:

    upright  = tolerance(|pitch|, 0.1 rad, 0.5 rad)
    forward  = 0.9 tolerance(|v error|, 0.1 m/s, 0.25 m/s) + 0.1 ramp(|v error|, 0.1, 2.0)
    turning  = 0.9 tolerance(|yaw rate error|, 0.1, 0.5) + 0.1 ramp(|yaw rate error|, 0.1, 2.0)
    reward   = 0.1 upright (0.1 + 0.9 (0.5 forward + 0.5 turning))

with the velocity the axle's true forward velocity and the yaw rate the gyro's.""",
        robot="two-wheel-steer",
        scenario="steer",
        command=_ENVELOPE,
        reward=TwistReward(),
        random_return=1.3204822078160736,
    ),
)
