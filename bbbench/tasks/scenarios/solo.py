"""`Solo`: one bot alone in its world, every single-bot task's scenario; and the tasks it
plays, a row each (`TASKS`), the two-wheel bot's and the wheel-legged robot's."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bbbench.robots.layout import SCAN_OFFSETS, observe
from bbbench.tasks.commands import FORWARD_TARGETS, SPEED_TARGETS, VELOCITY_TARGETS
from bbbench.tasks.perturbations import Push
from bbbench.tasks.reward import StayUpReward, stay_up_history, step_outcome
from bbbench.tasks.scenario import Outcome, Pose, Scenario, register_scenario
from bbbench.tasks.sensors import NoisySensors
from bbbench.tasks.spec import TaskSpec
from bbbench.terrain import Bumps, HeightfieldTerrain, ObstacleCourse, Obstacles, Slopes


@register_scenario
class Solo(Scenario):
    """One bot at the origin heading along +y, leaning U(-initial_pitch, initial_pitch);
    it observes its robot's layout through the task's sensors (then, with the height scan,
    the ground ahead), earns the shared reward for its own target, and a fall ends it."""

    name = "solo"
    summary = "one bot alone, at the origin heading along +y"
    senses = True
    scans_ground: ClassVar[bool] = True  # observes the height scan when the task asks

    @classmethod
    def refusal(cls, task) -> str | None:
        refused = super().refusal(task)
        if refused is None and task.height_scan and not cls.scans_ground:
            return f"{task.id}: the {cls.name!r} scenario observes no height scan"
        return refused

    def __init__(self, task) -> None:
        super().__init__(task)
        self.layout = self.robot.layout(task.height_scan)
        self._reward_of = step_outcome

    def starts(self, rng: np.random.Generator) -> tuple[list[Pose], list[float]]:
        pitch = self.task.initial_pitch
        return [((0.0, 0.0), 0.0)], [rng.uniform(-pitch, pitch)]

    def observe(
        self, scene: Any, states: list[Any], commands: list[float], targets: list[float], step: int
    ) -> list[np.ndarray]:
        """The bot's observation, as the one row of a list: its reading through the
        task's sensors, then what its robot adds; with the height scan, then the ground
        heights ahead of the axle."""
        state, command, target = states[0], commands[0], targets[0]
        if scene.true_five_only:  # perfect sensors, the shared five alone: the hot path
            return [observe(state.pitch, state.pitch_rate, state.wheel_speed, command, target)]
        reading = scene.reading(state, step)
        scan = None
        if self.task.height_scan:
            x, y, axle_height = state.axle
            scan = scene.ground.heights_along(x, y, state.heading, SCAN_OFFSETS, axle_height)
        return [self.robot.observe(reading, command, target, state, scan)]

    def outcome(
        self, agents: list[str], states: list[Any], targets: list[float], seed: int
    ) -> Outcome:
        """The step's reward, whether the bot fell (which ends its episode), and its
        info (`step_outcome`)."""
        reward, fell, info = self._reward_of(states[0], targets[0], self.reward)
        return Outcome((reward,), (fell,), fell, f"{agents[0]} fell" if fell else "", (info,))


# The tasks: each row states all it sets (`TaskSpec`'s defaults for the rest). A task's
# next version is a row of its own; the constants below are what versions share.
# The first rewards were `RewardWeights`; the latest versions score the shared reward in
# which staying up never costs (`StayUpReward`; `stay_up_history` says so in each).
# The -v1 terrain: on cells fine enough to have edges, on a strip that repeats across.
# Why each number is what it is: docs/notebook.md, "The terrain: why -v0 had no headroom,
# and what -v1 changes".
_V1_STRIP = dict(size=(2.4, 24.0), start_margin=1.0, lateral_period=1.2)
_V1_FINE_CELLS = 0.05
_WHY_V1 = """\
Why the terrain is built this way (speed, fine cells, a strip that repeats across and
follows the bot), from the robot's own numbers: docs/notebook.md, "The terrain: why -v0 had
no headroom, and what -v1 changes"; its calibration against PD is in docs/tasks.md."""

_FLAT_BALANCE_SUMMARY = "stay upright and in place on flat ground (the tutorial's task)"
_FLAT_BALANCE_DESCRIPTION = (
    "The tutorial's task. The target velocity is 0 throughout, the sensors are "
    "perfect, and the ground is an endless plane with the tutorial's friction. A "
    "policy that stands still scores close to the maximum return."
)
_VELOCITY_TRACKING_SUMMARY = "follow a target velocity in [-1, 1] m/s that changes every 2-5 s"
_VELOCITY_TRACKING_DESCRIPTION = (
    "Flat ground and perfect sensors, as in FlatBalance. The target forward "
    "velocity (observation 4) is piecewise constant: a value drawn uniformly from "
    "[-1, 1] m/s, held for a duration drawn uniformly from 2-5 s, then the next, "
    "all from the episode's seed. The reward's velocity term scores the axle's "
    "true forward velocity against it."
)
_NOISY_SENSORS_SUMMARY = "velocity tracking with a biased, noisy IMU and encoders"
_NOISY_SENSORS_DESCRIPTION = """\
VelocityTracking's ground and targets, observed through a biased, noisy IMU and noisy
encoders (the tutorial's noisy variant, now reproducible):

| Reading     | Per-episode bias   | Per-step noise (std) |
|-------------|--------------------|----------------------|
| pitch       | N(0, 0.1) rad      | 0.05 rad             |
| pitch_rate  | none               | 0.01 rad/s           |
| wheel_speed | none               | 0.05 rad/s           |

Bias and noise are drawn from the episode's seed; the wheel command and the target are
observed exactly. The reward uses the true state."""
_BUMPS_V1_SUMMARY = "cross short, steep random hills (up to ~21 deg) at 1-2 m/s"
_BUMPS_V1_DESCRIPTION = f"""\
The ground is a strip of random hills (white noise low-passed by a Gaussian of 0.1 m, on
0.05 m cells), a new one from each episode's seed, with flat ground around it. The bot
starts on a level pad 3 m from the strip's near end and must drive along it: the target
velocity is drawn from [1, 2] m/s and held 2-5 s at a time. Sensors are perfect.

`difficulty` (default 0.9, any number in [0, 1]) sets the hills' height, 0.01 m + 0.10 m
x difficulty, and with it their steepest slope: about 2 deg at 0, 13 deg at 0.5, 21 deg
at 0.9 (the default) and 23 deg at 1 (the mean over seeds of each map's steepest node).
Hills of 0.1 m features are shorter than the 0.24 m between the wheels: at 1-2 m/s the
wheels meet each one as a kick, not a climb, and the kicks lift them off the ground and
turn the bot. The value is recorded in `env.spec.kwargs` and changes the task's
fingerprint.

{_WHY_V1}"""
_BUMPS_V1_TERRAIN = HeightfieldTerrain(
    generator=Bumps(min_height=0.01, extra_height=0.10, feature_size=0.1),
    difficulty=0.9,
    **_V1_STRIP,
    cell_size=_V1_FINE_CELLS,
)
_BUMPS_V1_VERSION_HISTORY = (
    "v0: initial release.",
    "v1: terrain with headroom (on v0's hills, up to 0.08 m at 0.2-0.8 m/s, "
    "PD never fell): short hills (0.1 m features) up to 0.11 m and ~23 deg "
    "at difficulty 1, on 0.05 m cells, crossed at 1-2 m/s on a strip that "
    "repeats across (no side edge); default difficulty 0.9, where PD "
    "finishes 37% of the evaluation episodes.",
)
_OBSTACLES_V1_SUMMARY = "cross boxes and steps (up to 6 cm) with shrinking gaps at 1-2 m/s"
_OBSTACLES_V1_DESCRIPTION = f"""\
Along a strip of level ground on 0.05 m cells, obstacles follow one another, a new course
from each episode's seed (`ObstacleCourse`): 40% are full-width steps (a raised band
0.1-0.8 m deep: up, then down), the rest boxes 0.3-1.2 m across and 0.1-0.8 m deep
(repeating across the strip with the terrain). The bot cannot steer: a box under one
wheel turns it. Targets and start as in Bumps.

`difficulty` (default 0.5, in [0, 1]) sets the obstacles' height, each 25-100% of
0.01 m + 0.05 m x difficulty (at 1: 0.06 m, 0.6x the wheel radius, a face the wheel can
climb only with momentum), and their spacing: the gap before each is drawn from
[0.3, 2.0 - 1.7 x difficulty] m, so at difficulty 1 the next obstacle comes within
0.15-0.3 s at speed, before the bot has recovered from the last (no flat run-up).

{_WHY_V1}"""
_OBSTACLES_V1_TERRAIN = HeightfieldTerrain(
    generator=ObstacleCourse(),
    difficulty=0.5,
    **_V1_STRIP,
    cell_size=_V1_FINE_CELLS,
)
_OBSTACLES_V1_VERSION_HISTORY = (
    "v0: initial release.",
    "v1: terrain with headroom (v0's boxes and steps, up to 0.05 m on 0.2 m "
    "cells, were one-cell ramps at 0.2-0.8 m/s, and PD never fell): an "
    "obstacle course of boxes and full-width steps up to 0.06 m (0.6x the "
    "wheel radius) on 0.05 m cells, gaps shrinking to 0.3 m at difficulty 1, "
    "crossed at 1-2 m/s on a strip that repeats across (no side edge); "
    "default difficulty 0.5, where PD finishes 36% of the evaluation episodes.",
)
_SLOPES_V1_SUMMARY = "climb and descend ramps (up to ~26 deg) at 1-2 m/s"
_SLOPES_V1_DESCRIPTION = f"""\
A strip on 0.1 m cells, level across and ramped along the driving direction: ramps
0.3-1.5 m long, each inclined up or down by an angle drawn up to 0.5 rad x difficulty,
heights kept within [0, 2] m (a ramp that would leave them levels off), a new profile
from each episode's seed (`Slopes`). Targets and start as in Bumps: the command asks for
1-2 m/s up and down.

`difficulty` (default 0.9, in [0, 1]) sets the steepest ramp: 0 at 0, 14 deg at 0.5,
26 deg at 0.9 (the default), 29 deg at 1. Holding a speed on a ramp needs a lean into it
(about 0.2 rad at 20 deg for this bot's 1.57 N m/rad of torso weight torque); the kink
where an up-ramp meets a down-ramp changes that lean at once, and at 2 m/s the wheels
leave the crest. On ramps of at most 20 deg (difficulty 0.7) PD finishes about two thirds
of the episodes, too many for the calibration: the default is steeper than that.

{_WHY_V1}"""
_SLOPES_V1_TERRAIN = HeightfieldTerrain(
    generator=Slopes(min_incline=0.0, extra_incline=0.5, max_height=2.0, ramp_length=(0.3, 1.5)),
    difficulty=0.9,
    size=(3.2, 32.0),
    start_margin=1.0,
    lateral_period=1.6,
    cell_size=0.1,
)
_SLOPES_V1_VERSION_HISTORY = (
    "v1: initial release, with the -v1 terrain tasks (there is no v0): ramps "
    "0.3-1.5 m long up to 0.5 rad (29 deg) at difficulty 1, within 0-2 m of "
    "height, on 0.1 m cells, climbed and descended at 1-2 m/s; default "
    "difficulty 0.9 (26 deg), where PD finishes 55% of the evaluation episodes.",
)

# The wheel-legged robot's tasks (`bbbench.robots.wheel_legged`): the two-wheel tasks'
# ground generators, commands, reward and evaluation seeds, so that the same seed is the
# same ground and the same targets for either robot (docs/tasks.md compares them).
_LEGGED_WHY = """\
The wheel-legged robot (`bbbench.robots.wheel_legged`, whose docstring has its facts): a
torso on two legs, each with an actuated hip and knee and a driven wheel; 1.2 kg, 0.1 m
wheels. It acts through 6 continuous values, the four leg targets then each wheel's
change of commanded speed, and observes the five shared values, then its legs' angles
and rates, its roll and the wheels' differences (the tables: the task's env docstring,
and docs/robots.md)."""
_LEGGED_HISTORY = ("v0: initial release, on the shared reward (StayUpReward).",)


def _legged(description: str) -> str:
    return f"{description}\n\n{_LEGGED_WHY}"


TASKS = (
    TaskSpec(
        id="bbbench/FlatBalance-v0",
        summary=_FLAT_BALANCE_SUMMARY,
        description=_FLAT_BALANCE_DESCRIPTION,
        random_return=4.265516002827753,
    ),
    TaskSpec(
        id="bbbench/FlatBalance-v1",
        summary=_FLAT_BALANCE_SUMMARY,
        description=_FLAT_BALANCE_DESCRIPTION,
        random_return=4.932770048552165,
        reward=StayUpReward(),
        version_history=stay_up_history(("v0: initial release.",), 1),
    ),
    TaskSpec(
        id="bbbench/VelocityTracking-v0",
        summary=_VELOCITY_TRACKING_SUMMARY,
        description=_VELOCITY_TRACKING_DESCRIPTION,
        random_return=1.2860367754813657,
        command=VELOCITY_TARGETS,
    ),
    TaskSpec(
        id="bbbench/VelocityTracking-v1",
        summary=_VELOCITY_TRACKING_SUMMARY,
        description=_VELOCITY_TRACKING_DESCRIPTION,
        random_return=2.1504693078292174,
        command=VELOCITY_TARGETS,
        reward=StayUpReward(),
        version_history=stay_up_history(("v0: initial release.",), 1),
    ),
    TaskSpec(
        id="bbbench/NoisySensors-v0",
        summary=_NOISY_SENSORS_SUMMARY,
        description=_NOISY_SENSORS_DESCRIPTION,
        random_return=1.2860367754813657,
        command=VELOCITY_TARGETS,
        sensors=NoisySensors(),
    ),
    TaskSpec(
        id="bbbench/NoisySensors-v1",
        summary=_NOISY_SENSORS_SUMMARY,
        description=_NOISY_SENSORS_DESCRIPTION,
        random_return=2.1504693078292174,
        command=VELOCITY_TARGETS,
        sensors=NoisySensors(),
        reward=StayUpReward(),
        version_history=stay_up_history(("v0: initial release.",), 1),
    ),
    TaskSpec(
        id="bbbench/Bumps-v0",
        summary="drive forward at 0.2-0.8 m/s across smooth random hills",
        description=(
            "An 8 x 20 m strip of smooth random hills (0.35 m features, 0.2 m cells), a new "
            "one from each episode's seed, 0.02 m high at difficulty 0 and 0.08 m at 1 "
            "(default 0.3), driven along at 0.2-0.8 m/s. Sensors are perfect."
        ),
        random_return=1.781347180609098,
        terrain=HeightfieldTerrain(generator=Bumps(), difficulty=0.3),
        command=FORWARD_TARGETS,
    ),
    TaskSpec(
        id="bbbench/Obstacles-v0",
        summary="drive forward at 0.2-0.8 m/s over scattered boxes and steps",
        description=(
            "An 8 x 20 m strip on 0.2 m cells with scattered boxes and steps, 0.015-0.05 m "
            "high (default difficulty 0.3), a new layout from each episode's seed, driven "
            "along at 0.2-0.8 m/s. Sensors are perfect."
        ),
        random_return=1.777879984692359,
        terrain=HeightfieldTerrain(generator=Obstacles(), difficulty=0.3),
        command=FORWARD_TARGETS,
    ),
    TaskSpec(
        id="bbbench/Bumps-v1",
        summary=_BUMPS_V1_SUMMARY,
        description=_BUMPS_V1_DESCRIPTION,
        random_return=-5.935016249898391,
        terrain=_BUMPS_V1_TERRAIN,
        command=SPEED_TARGETS,
        version_history=_BUMPS_V1_VERSION_HISTORY,
    ),
    TaskSpec(
        id="bbbench/Bumps-v2",
        summary=_BUMPS_V1_SUMMARY,
        description=_BUMPS_V1_DESCRIPTION,
        random_return=0.773599543444995,
        terrain=_BUMPS_V1_TERRAIN,
        command=SPEED_TARGETS,
        reward=StayUpReward(),
        version_history=stay_up_history(_BUMPS_V1_VERSION_HISTORY, 2),
    ),
    TaskSpec(
        id="bbbench/Obstacles-v1",
        summary=_OBSTACLES_V1_SUMMARY,
        description=_OBSTACLES_V1_DESCRIPTION,
        random_return=-5.9759097239538495,
        terrain=_OBSTACLES_V1_TERRAIN,
        command=SPEED_TARGETS,
        version_history=_OBSTACLES_V1_VERSION_HISTORY,
    ),
    TaskSpec(
        id="bbbench/Obstacles-v2",
        summary=_OBSTACLES_V1_SUMMARY,
        description=_OBSTACLES_V1_DESCRIPTION,
        random_return=0.774324478721841,
        terrain=_OBSTACLES_V1_TERRAIN,
        command=SPEED_TARGETS,
        reward=StayUpReward(),
        version_history=stay_up_history(_OBSTACLES_V1_VERSION_HISTORY, 2),
    ),
    TaskSpec(
        id="bbbench/Slopes-v1",
        summary=_SLOPES_V1_SUMMARY,
        description=_SLOPES_V1_DESCRIPTION,
        random_return=-5.9305729273501235,
        terrain=_SLOPES_V1_TERRAIN,
        command=SPEED_TARGETS,
        version_history=_SLOPES_V1_VERSION_HISTORY,
    ),
    TaskSpec(
        id="bbbench/Slopes-v2",
        summary=_SLOPES_V1_SUMMARY,
        description=_SLOPES_V1_DESCRIPTION,
        random_return=0.7804649229704179,
        terrain=_SLOPES_V1_TERRAIN,
        command=SPEED_TARGETS,
        reward=StayUpReward(),
        version_history=stay_up_history(_SLOPES_V1_VERSION_HISTORY, 2),
    ),
    TaskSpec(
        id="bbbench/PushRecovery-v0",
        summary="stay up and in place while shoved, harder each time, every 2-4 s",
        description="""\
FlatBalance's flat ground, target (0 m/s) and perfect sensors, with shoves: every 2-4 s
(each wait drawn from the episode's seed) the torso is pushed horizontally, forward or
back with equal odds, by an impulse that grows over the episode, 0.5 N s plus 0.068 N s
per second (0.5 N s at the start, about 1.5 N s at the end; 1 N s changes the 1 kg bot's
speed by about 1 m/s). The pushes are the `push` perturbation with a growth
(`bbbench.tasks.perturbations.Push`): the keyword `push=` sets the first push's impulse
and keeps the growth. Calibrated against PD, which stays up through 47 of the 100
evaluation episodes (docs/tasks.md, "PushRecovery").""",
        reward=StayUpReward(),
        perturbations=(Push(impulse=0.5, growth=0.068),),
        version_history=("v0: initial release, on the shared reward (StayUpReward).",),
        random_return=4.932770048552165,
    ),
    TaskSpec(
        id="bbbench/LeggedFlatBalance-v0",
        robot="wheel-legged",
        summary="the wheel-legged robot: stay upright and in place on flat ground",
        description=_legged(
            "FlatBalance-v1's task (flat ground, target 0 m/s, perfect sensors) for the "
            "wheel-legged robot."
        ),
        reward=StayUpReward(),
        version_history=_LEGGED_HISTORY,
        random_return=4.422148803963744,
    ),
    TaskSpec(
        id="bbbench/LeggedVelocityTracking-v0",
        robot="wheel-legged",
        summary="the wheel-legged robot: follow a target velocity in [-1, 1] m/s",
        description=_legged(
            "VelocityTracking-v1's task (flat ground, a target drawn from [-1, 1] m/s and held "
            "2-5 s at a time, perfect sensors) for the wheel-legged robot."
        ),
        reward=StayUpReward(),
        command=VELOCITY_TARGETS,
        version_history=_LEGGED_HISTORY,
        random_return=1.8687276402909736,
    ),
    TaskSpec(
        id="bbbench/LeggedBumps-v0",
        robot="wheel-legged",
        summary="the wheel-legged robot: cross short random hills up to 0.22 m at 1-2 m/s",
        description=_legged(
            """\
Bumps-v2's strip, start, targets (1-2 m/s) and sensors, with hills more than twice as
high: 0.01 m + 0.25 m x difficulty (default 0.85: 0.22 m, 2.2 wheel radii), on the same
0.1 m features and 0.05 m cells. Calibrated against the robot's classical controller
(`bbbench.policies.controllers.legged`), which finishes 48 of the 100 evaluation episodes; on
Bumps-v2's own hills it finishes all of them (docs/tasks.md)."""
        ),
        reward=StayUpReward(),
        command=SPEED_TARGETS,
        terrain=HeightfieldTerrain(
            generator=Bumps(min_height=0.01, extra_height=0.25, feature_size=0.1),
            difficulty=0.85,
            **_V1_STRIP,
            cell_size=_V1_FINE_CELLS,
        ),
        version_history=_LEGGED_HISTORY,
        random_return=0.6793066639662371,
    ),
    TaskSpec(
        id="bbbench/LeggedObstacles-v0",
        robot="wheel-legged",
        summary="the wheel-legged robot: cross boxes and steps (up to 5 cm) at 1-2 m/s",
        description=_legged(
            """\
Obstacles-v2's course, start, targets (1-2 m/s) and sensors at a higher default
difficulty, 0.8 (obstacles up to 0.01 m + 0.05 m x 0.8 = 0.05 m, each gap drawn from
[0.3, 0.64] m). Calibrated against the robot's classical controller
(`bbbench.policies.controllers.legged`), which finishes 47 of the 100 evaluation episodes
(docs/tasks.md)."""
        ),
        reward=StayUpReward(),
        command=SPEED_TARGETS,
        terrain=HeightfieldTerrain(
            generator=ObstacleCourse(), difficulty=0.8, **_V1_STRIP, cell_size=_V1_FINE_CELLS
        ),
        version_history=_LEGGED_HISTORY,
        random_return=0.6740527046489759,
    ),
)
