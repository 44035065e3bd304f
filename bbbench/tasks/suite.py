"""The suite: a table of task IDs to specs, registered with gymnasium from that table."""

from __future__ import annotations

import dataclasses
import difflib
from typing import Any

import gymnasium
from gymnasium import spaces

from bbbench.tasks.commands import PiecewiseConstantVelocity
from bbbench.tasks.coupling import Beam, Tether
from bbbench.tasks.group import Group
from bbbench.tasks.perturbations import Push
from bbbench.tasks.reward import StayUpReward
from bbbench.tasks.sensors import NoisySensors
from bbbench.tasks.spec import TaskSpec
from bbbench.terrain import Bumps, HeightfieldTerrain, ObstacleCourse, Obstacles, Slopes

_VELOCITY_TARGETS = PiecewiseConstantVelocity(low=-1.0, high=1.0, hold=(2.0, 5.0))
# On terrain the bot must make progress across it: forward targets only.
_FORWARD_TARGETS = PiecewiseConstantVelocity(low=0.2, high=0.8, hold=(2.0, 5.0))
# The -v1 terrain: crossed at speed, on cells fine enough to have edges, on a strip that
# repeats across. Why each number is what it is: docs/tasks.md, "The terrain: why -v0 had
# no headroom, and what -v1 changes".
_SPEED_TARGETS = PiecewiseConstantVelocity(low=1.0, high=2.0, hold=(2.0, 5.0))
_V1_STRIP = dict(size=(2.4, 24.0), start_margin=1.0, lateral_period=1.2)
_V1_FINE_CELLS = 0.05
_WHY_V1 = """\
Why the terrain is built this way (speed, fine cells, a strip that repeats across and
follows the bot), from the robot's own numbers: docs/tasks.md, "The terrain: why -v0 had
no headroom, and what -v1 changes"; its calibration against PD is the table after it."""

_PUBLISHED = (
    TaskSpec(
        id="bbbench/FlatBalance-v0",
        summary="stay upright and in place on flat ground (the tutorial's task)",
        description=(
            "The tutorial's task. The target velocity is 0 throughout, the sensors are "
            "perfect, and the ground is an endless plane with the tutorial's friction. A "
            "policy that stands still scores close to the maximum return."
        ),
        random_return=4.265516002827753,
    ),
    TaskSpec(
        id="bbbench/VelocityTracking-v0",
        summary="follow a target velocity in [-1, 1] m/s that changes every 2-5 s",
        description=(
            "Flat ground and perfect sensors, as in FlatBalance. The target forward "
            "velocity (observation 4) is piecewise constant: a value drawn uniformly from "
            "[-1, 1] m/s, held for a duration drawn uniformly from 2-5 s, then the next, "
            "all from the episode's seed. The reward's velocity term scores the axle's "
            "true forward velocity against it."
        ),
        random_return=1.2860367754813657,
        command=_VELOCITY_TARGETS,
    ),
    TaskSpec(
        id="bbbench/NoisySensors-v0",
        summary="velocity tracking with a biased, noisy IMU and encoders",
        description="""\
VelocityTracking's ground and targets, observed through a biased, noisy IMU and noisy
encoders (the tutorial's noisy variant, now reproducible):

| Reading     | Per-episode bias   | Per-step noise (std) |
|-------------|--------------------|----------------------|
| pitch       | N(0, 0.1) rad      | 0.05 rad             |
| pitch_rate  | none               | 0.01 rad/s           |
| wheel_speed | none               | 0.05 rad/s           |

Bias and noise are drawn from the episode's seed; the wheel command and the target are
observed exactly. The reward uses the true state.""",
        random_return=1.2860367754813657,
        command=_VELOCITY_TARGETS,
        sensors=NoisySensors(),
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
        command=_FORWARD_TARGETS,
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
        command=_FORWARD_TARGETS,
    ),
    TaskSpec(
        id="bbbench/Bumps-v1",
        summary="cross short, steep random hills (up to ~21 deg) at 1-2 m/s",
        description=f"""\
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

{_WHY_V1}""",
        random_return=-5.935016249898391,
        terrain=HeightfieldTerrain(
            generator=Bumps(min_height=0.01, extra_height=0.10, feature_size=0.1),
            difficulty=0.9,
            **_V1_STRIP,
            cell_size=_V1_FINE_CELLS,
        ),
        command=_SPEED_TARGETS,
        version_history=(
            "v0: initial release.",
            "v1: terrain with headroom (on v0's hills, up to 0.08 m at 0.2-0.8 m/s, "
            "PD never fell): short hills (0.1 m features) up to 0.11 m and ~23 deg "
            "at difficulty 1, on 0.05 m cells, crossed at 1-2 m/s on a strip that "
            "repeats across (no side edge); default difficulty 0.9, where PD "
            "finishes 37% of the evaluation episodes.",
        ),
    ),
    TaskSpec(
        id="bbbench/Obstacles-v1",
        summary="cross boxes and steps (up to 6 cm) with shrinking gaps at 1-2 m/s",
        description=f"""\
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

{_WHY_V1}""",
        random_return=-5.9759097239538495,
        terrain=HeightfieldTerrain(
            generator=ObstacleCourse(),
            difficulty=0.5,
            **_V1_STRIP,
            cell_size=_V1_FINE_CELLS,
        ),
        command=_SPEED_TARGETS,
        version_history=(
            "v0: initial release.",
            "v1: terrain with headroom (v0's boxes and steps, up to 0.05 m on 0.2 m "
            "cells, were one-cell ramps at 0.2-0.8 m/s, and PD never fell): an "
            "obstacle course of boxes and full-width steps up to 0.06 m (0.6x the "
            "wheel radius) on 0.05 m cells, gaps shrinking to 0.3 m at difficulty 1, "
            "crossed at 1-2 m/s on a strip that repeats across (no side edge); "
            "default difficulty 0.5, where PD finishes 36% of the evaluation episodes.",
        ),
    ),
    TaskSpec(
        id="bbbench/Slopes-v1",
        summary="climb and descend ramps (up to ~26 deg) at 1-2 m/s",
        description=f"""\
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

{_WHY_V1}""",
        random_return=-5.9305729273501235,
        terrain=HeightfieldTerrain(
            generator=Slopes(
                min_incline=0.0, extra_incline=0.5, max_height=2.0, ramp_length=(0.3, 1.5)
            ),
            difficulty=0.9,
            size=(3.2, 32.0),
            start_margin=1.0,
            lateral_period=1.6,
            cell_size=0.1,
        ),
        command=_SPEED_TARGETS,
        version_history=(
            "v1: initial release, with the -v1 terrain tasks (there is no v0): ramps "
            "0.3-1.5 m long up to 0.5 rad (29 deg) at difficulty 1, within 0-2 m of "
            "height, on 0.1 m cells, climbed and descended at 1-2 m/s; default "
            "difficulty 0.9 (26 deg), where PD finishes 55% of the evaluation episodes.",
        ),
    ),
    TaskSpec(
        id="bbbench/MultiBalance-v0",
        summary="4 bots (2-16) whose paths cross on flat ground, each at 0.2-0.8 m/s",
        description=(
            "Several bots (4 by default, `n_bots` 2-16) start on a circle facing its centre, "
            "so their paths cross, on flat ground; each follows its own forward target at "
            "0.2-0.8 m/s and leaves the episode when it falls. `bbbench.envs.multi."
            "MultiBalanceEnv` documents the PettingZoo API they share."
        ),
        random_return=1.5245667657055884,
        command=_FORWARD_TARGETS,
        group=Group(),
    ),
    TaskSpec(
        id="bbbench/MultiBumps-v0",
        summary="4 bots (2-16) whose paths cross on smooth random hills",
        description=(
            "MultiBalance's bots and targets on a 12 x 12 m square of -v0's smooth random "
            "hills (0.3 default difficulty) around the spawn circle, level along it."
        ),
        random_return=1.5233704486135895,
        terrain=HeightfieldTerrain(
            generator=Bumps(),
            difficulty=0.3,
            # A square around the spawn circle, level along it.
            size=(12.0, 12.0),
            start_margin=6.0,
            start_ring=Group().spawn_radius,
        ),
        command=_FORWARD_TARGETS,
        group=Group(),
    ),
)


def _staying_up_never_costs(task: TaskSpec, version: int, random_return: float) -> TaskSpec:
    """`task` as version `version`: the same robot, dynamics, terrain, commands, sensors and
    evaluation seeds, scored by the shared reward in which staying up never costs."""
    name = task.id.rsplit("-v", 1)[0]
    change = (
        f"v{version}: the shared reward in which staying up never costs (StayUpReward: each "
        f"step earns 0-0.1, 0.01 for being upright and up to 0.09 more for tracking the "
        f"target velocity; docs/tasks.md says why); robot, dynamics, terrain, commands, "
        f"sensors and evaluation seeds as v{task.version}."
    )
    return dataclasses.replace(
        task,
        id=f"{name}-v{version}",
        reward=StayUpReward(),
        version_history=(*task.version_history, change),
        random_return=random_return,
    )


# Every task's latest version: the published ones re-scored by the new shared reward
# (`bbbench.tasks.reward`). The earlier versions stay registered, unchanged.
_STAY_UP = (
    ("bbbench/FlatBalance-v0", 1, 4.932770048552165),
    ("bbbench/VelocityTracking-v0", 1, 2.1504693078292174),
    ("bbbench/NoisySensors-v0", 1, 2.1504693078292174),
    ("bbbench/Bumps-v1", 2, 0.773599543444995),
    ("bbbench/Obstacles-v1", 2, 0.774324478721841),
    ("bbbench/Slopes-v1", 2, 0.7804649229704179),
    ("bbbench/MultiBalance-v0", 1, 1.72400817656264),
    ("bbbench/MultiBumps-v0", 1, 1.7237354574632304),
)

SUITE: dict[str, TaskSpec] = {spec.id: spec for spec in _PUBLISHED}
SUITE.update(
    (new.id, new)
    for new in (
        _staying_up_never_costs(SUITE[task_id], version, random_return)
        for task_id, version, random_return in _STAY_UP
    )
)

# Tasks first published on the shared reward.
_PUSH_RECOVERY = TaskSpec(
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
    random_return=4.932770048552165,  # the random policy falls before the first push
)
SUITE[_PUSH_RECOVERY.id] = _PUSH_RECOVERY

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


def _legged(
    task_id: str, like: str, summary: str, description: str, random_return: float, **changes
) -> TaskSpec:
    """The task `like` played by the wheel-legged robot, as `task_id`."""
    return dataclasses.replace(
        SUITE[like],
        id=task_id,
        robot="wheel-legged",
        summary=summary,
        description=f"{description}\n\n{_LEGGED_WHY}",
        version_history=_LEGGED_HISTORY,
        random_return=random_return,
        **changes,
    )


_LEGGED = (
    _legged(
        "bbbench/LeggedFlatBalance-v0",
        "bbbench/FlatBalance-v1",
        "the wheel-legged robot: stay upright and in place on flat ground",
        "FlatBalance-v1's task (flat ground, target 0 m/s, perfect sensors) for the "
        "wheel-legged robot.",
        random_return=4.422148803963744,
    ),
    _legged(
        "bbbench/LeggedVelocityTracking-v0",
        "bbbench/VelocityTracking-v1",
        "the wheel-legged robot: follow a target velocity in [-1, 1] m/s",
        "VelocityTracking-v1's task (flat ground, a target drawn from [-1, 1] m/s and held "
        "2-5 s at a time, perfect sensors) for the wheel-legged robot.",
        random_return=1.8687276402909736,
    ),
    _legged(
        "bbbench/LeggedBumps-v0",
        "bbbench/Bumps-v2",
        "the wheel-legged robot: cross short random hills up to 0.22 m at 1-2 m/s",
        """\
Bumps-v2's strip, start, targets (1-2 m/s) and sensors, with hills more than twice as
high: 0.01 m + 0.25 m x difficulty (default 0.85: 0.22 m, 2.2 wheel radii), on the same
0.1 m features and 0.05 m cells. Calibrated against the robot's classical controller
(`bbbench.policies.legged`), which finishes 48 of the 100 evaluation episodes; on
Bumps-v2's own hills it finishes all of them (docs/tasks.md).""",
        random_return=0.6793066639662371,
        terrain=dataclasses.replace(
            SUITE["bbbench/Bumps-v2"].terrain,
            generator=Bumps(min_height=0.01, extra_height=0.25, feature_size=0.1),
            difficulty=0.85,
        ),
    ),
    _legged(
        "bbbench/LeggedObstacles-v0",
        "bbbench/Obstacles-v2",
        "the wheel-legged robot: cross boxes and steps (up to 5 cm) at 1-2 m/s",
        """\
Obstacles-v2's course, start, targets (1-2 m/s) and sensors at a higher default
difficulty, 0.8 (obstacles up to 0.01 m + 0.05 m x 0.8 = 0.05 m, each gap drawn from
[0.3, 0.64] m). Calibrated against the robot's classical controller
(`bbbench.policies.legged`), which finishes 47 of the 100 evaluation episodes
(docs/tasks.md).""",
        random_return=0.6740527046489759,
        terrain=dataclasses.replace(SUITE["bbbench/Obstacles-v2"].terrain, difficulty=0.8),
    ),
)
SUITE.update((task.id, task) for task in _LEGGED)

# Teams in a column (`bbbench.tasks.scenarios.column`): coupled bots, one team reward, led
# by the front bot, the only one that observes the target. MultiBalance-v1's row (its
# reward, control rate, time limit and evaluation seeds) with a column scenario, a
# coupling and targets fast enough that bots which ignore the coupling are thrown.
_TEAM_TARGETS = PiecewiseConstantVelocity(low=-2.0, high=2.0, hold=(2.0, 5.0))
_TEAM_HISTORY = ("v0: initial release, on the shared reward's team form (Column).",)
_TEAM_WHY = """\
Only the front bot observes the team's target velocity; the others read 0 in that slot
and must infer it from the coupling and from their neighbours. Targets are drawn from
[-2, 2] m/s (the bot's top speed is 2.46 m/s) and held 2-5 s, as VelocityTracking's: at
these speeds bots that ignore each other are thrown (at [-1, 1] m/s a hinged beam never
threw PD). Every agent receives the team's reward, `StayUpReward.terms(pitch, error)`
with the most tilted bot's pitch and `error` = |team velocity - target|: each step earns
0-0.1, 0.01 for the team being upright and up to 0.09 more for its tracking. A fall of
any bot ends every agent's episode (multiwalker's `terminate_on_fall`). The observation
(19 values per bot, the table in `bbbench.envs.multi`): the shared five, four of the
coupling, then the bot ahead and the bot behind, each with a presence bit. The naive
baseline is `pd` (a follower holds the 0 it observes); the classical team controller is
`team` (`bbbench.policies.team`); docs/tasks.md has the calibration."""


def _team(task_id: str, summary: str, description: str, random_return: float, **fields):
    """A column task on MultiBalance-v1's row (3 bots by default, `n_bots` 2-4)."""
    return dataclasses.replace(
        SUITE["bbbench/MultiBalance-v1"],
        id=task_id,
        summary=summary,
        description=f"{description}\n\n{_TEAM_WHY}",
        group=Group(n_bots=3),
        command=_TEAM_TARGETS,
        version_history=_TEAM_HISTORY,
        random_return=random_return,
        **fields,
    )


_BEAM_TABLE = """\
| beam | value |
|---|---|
| mass | 1.5 kg |
| length | (N - 1) x 0.6 m + 2 x 0.1 m (1.4 m for 3 bots) |
| cross-section | 0.3 m across (along the axles) x 0.04 m high |
| spacing | 0.6 m between neighbouring bots' hinges |
| hinges | per bot, two point-to-point constraints 0.2 m apart on its torso's top: a hinge |
| collisions | the ground only, not the bots |
| target range | [-2, 2] m/s, each held 2-5 s |

`payload_mass` loads the beam (kg at its centre); `com_offset` does not apply."""

_TEAMS = (
    _team(
        "bbbench/BeamCarry-v0",
        "a team of 3 bots (2-4) carrying one beam, led by the front bot, at [-2, 2] m/s",
        f"""\
A column of bots (3 by default, `n_bots` 2-4) on one heading, 0.6 m apart, carries one
beam hinged to the top of every torso (`BeamCarry`, `Beam`) on flat ground. The team's
velocity is the beam's, along its length. Each bot observes the force its hinges exert on
it along the beam and square to it, and the beam's pitch and pitch rate.

{_BEAM_TABLE}""",
        random_return=1.9037218152528517,
        scenario="beam-carry",
        coupling=Beam(),
    ),
    _team(
        "bbbench/Convoy-v0",
        "a convoy of 3 bots (2-4), each tethered to the next, led by the front bot",
        """\
A column of bots (3 by default, `n_bots` 2-4) on one heading, each tethered to the next
by a spring-damper between their torsos' centres of mass (`Convoy`, `Tether`) on flat
ground. A tether pulls, never pushes: 20 N/m x (length - 0.6 m) + 5 N s/m x (its rate),
applied to both bots before every world step; stretched more than 0.4 m beyond its rest
length it breaks, and the team's episode ends. The bots start 0.6 m apart (the rest
length). The team's velocity is the bots' mean forward velocity. Each bot observes the
stretch of the tether ahead and of the one behind, and their rates (0 where there is
none).""",
        random_return=0.9912909542770169,
        scenario="convoy",
        coupling=Tether(),
    ),
)
SUITE.update((task.id, task) for task in _TEAMS)
_BEAM_BUMPS = _team(
    "bbbench/BeamCarryBumps-v0",
    "BeamCarry's team and beam over smooth random hills (`difficulty=` 0..1)",
    f"""\
BeamCarry's team, beam and targets on a 4 x 36 m strip of smooth random hills (Bumps'
generator: white noise low-passed by a Gaussian of 0.35 m, on 0.2 m cells), a new one
from each episode's seed, with flat ground around it. The column starts centred on a
level disc of 1.2 m radius in the strip's middle, so that it can drive 18 m either way.
`difficulty` (default 0.6, any number in [0, 1]) sets the hills' height, 0.02 m + 0.10 m
x difficulty (0.08 m at the default, as high as Bumps-v0's at difficulty 1). On a hill the
beam pitches: the hinges' force along it carries part of its weight.

{_BEAM_TABLE}""",
    random_return=1.9029908268947455,
    scenario="beam-carry",
    coupling=Beam(),
    terrain=HeightfieldTerrain(
        generator=Bumps(extra_height=0.10),
        difficulty=0.6,
        size=(4.0, 36.0),
        start_margin=18.0,
        start_pad=1.2,
    ),
)
SUITE[_BEAM_BUMPS.id] = _BEAM_BUMPS


def entry_point(task_id: str) -> str:
    """What plays a task: `bbbench.envs.task_envs.entry_point` every single-bot task (as
    the class made from its row), `MultiBalanceEnv` every multi-bot task."""
    if SUITE[task_id].multi_agent:
        return "bbbench.envs.multi:MultiBalanceEnv"
    return "bbbench.envs.task_envs:entry_point"


def register_suite() -> None:
    """Register every task of the suite with gymnasium (idempotent).

    Multi-bot tasks are PettingZoo environments, which `gymnasium.make` cannot
    build: their IDs are registered so that `gymnasium.make` says to use
    `bbbench.make_parallel` (or `bbbench.make_vec`) instead of "no such env".
    """
    for task in SUITE.values():
        if task.id in gymnasium.registry:
            continue
        if task.multi_agent:
            gymnasium.register(
                id=task.id, entry_point=not_a_gymnasium_env, kwargs={"task": task.id}
            )
            continue
        kwargs = {"task": task.id}
        if task.difficulty is not None:  # recorded in env.spec, default or not
            kwargs["difficulty"] = task.difficulty
        gymnasium.register(
            id=task.id,
            entry_point=entry_point(task.id),
            kwargs=kwargs,
            max_episode_steps=task.max_episode_steps,
        )


def not_a_gymnasium_env(task: str, **kwargs: Any) -> gymnasium.Env:
    """What `gymnasium.make` of a multi-bot task calls: an error that says what to use."""
    raise ValueError(multi_bot_hint(task))


def multi_bot_hint(task_id: str) -> str:
    return (
        f"{task_id} is a multi-bot (PettingZoo) task: make it with "
        f"bbbench.make_parallel({task_id!r}), or bbbench.make_vec for stable-baselines3"
    )


def list_tasks(multi_agent: bool | None = None, latest: bool = False) -> list[str]:
    """The IDs of the suite's tasks, sorted: all, or only multi-bot (True) or single-bot
    (False); with `latest`, only the newest version of each task (what the leaderboard
    ranks and `bbbench eval` plays unless told otherwise)."""
    return sorted(
        task_id
        for task_id, task in SUITE.items()
        if (multi_agent is None or task.multi_agent == multi_agent)
        and (not latest or latest_version(task_id) == task_id)
    )


def latest_version(task_id: str) -> str:
    """The newest version of `task_id`'s task: 'bbbench/Bumps-v2' for 'bbbench/Bumps-v0'."""
    name = spec(task_id).name
    return max((task for task in SUITE.values() if task.name == name), key=_version).id


def _version(task: TaskSpec) -> int:
    return task.version


def spec(task_id: str) -> TaskSpec:
    """The frozen spec of a task; a clear error, naming the closest IDs, for an unknown one."""
    try:
        return SUITE[task_id]
    except (KeyError, TypeError):
        pass
    close = difflib.get_close_matches(str(task_id), list(SUITE), n=3, cutoff=0.5)
    if not close and isinstance(task_id, str):
        # "FlatBalance-v0" without the namespace, or any case.
        close = [known for known in SUITE if known.lower().endswith(task_id.lower())]
    hint = f" Did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    raise ValueError(
        f"unknown task {task_id!r}.{hint} Known tasks: {', '.join(list_tasks())} "
        f"(see `bbbench list`)."
    )


def agent_spaces(
    task_id: str, action_mode: str, height_scan: bool = False
) -> tuple[spaces.Box, spaces.Space]:
    """The observation and action space of one bot of a task (every bot's, on a multi-bot
    task, which has no height scan: its scenario's), without building the task's world."""
    task = spec(task_id)
    robot = task.robot_model
    if task.group is None:
        return robot.observation_space(height_scan), robot.action_space(action_mode)
    return task.scenario_class(task).observation_space(), robot.action_space(action_mode)
