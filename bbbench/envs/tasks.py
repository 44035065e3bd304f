"""One class per task, so that each task has its own documentation.

All of them are `BalanceEnv`, which documents the interface they share (action
and observation tables, reward, starting state, episode end); a class here
names its task, says what differs, and carries the task's Version History,
which is read from the suite's spec table so the two cannot disagree. A new
version of a task (`-v1`) is a new row of the table, played by the same class.

`gymnasium.make(id)` builds the class named after the task: `bbbench/Bumps-v0`
is played by `BumpsEnv`.
"""

from __future__ import annotations

from typing import Any

from bbbench.envs.balance import BalanceEnv
from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import SUITE


def _with_version_history(cls: type[BalanceEnv]) -> type[BalanceEnv]:
    """Append the Version History of every version of the class's task to its docstring."""
    name = cls.__name__.removesuffix("Env")
    versions = [spec for spec in SUITE.values() if spec.name == name]
    if not versions:
        raise LookupError(f"{cls.__name__} plays no task of the suite (no bbbench/{name}-vN)")
    newest = max(versions, key=lambda spec: spec.version)
    history = "\n".join(f"    - {entry}" for entry in newest.version_history)
    cls.__doc__ = f"{cls.__doc__.rstrip()}\n\n    ## Version History\n\n{history}\n"
    cls.default_task = newest.id
    return cls


class _TaskEnv(BalanceEnv):
    default_task: str

    def __init__(self, task: str | TaskSpec | None = None, **kwargs: Any) -> None:
        super().__init__(task=self.default_task if task is None else task, **kwargs)


@_with_version_history
class FlatBalanceEnv(_TaskEnv):
    """`bbbench/FlatBalance-v1`: stay upright and in place on flat ground.

    The tutorial's task. The target velocity is 0 throughout, the sensors are
    perfect, and the ground is an endless plane with the tutorial's friction.
    A policy that stands still scores close to the maximum return, 150.

    `bbbench/FlatBalance-v0` is the same task under the first reward (kept for
    comparability).

    Everything shared by the suite (actions, observations, reward, starting
    state, episode end, keyword arguments) is documented in `BalanceEnv`.
    """


@_with_version_history
class VelocityTrackingEnv(_TaskEnv):
    """`bbbench/VelocityTracking-v1`: follow a target velocity that changes.

    Flat ground and perfect sensors, as in FlatBalance. The target forward
    velocity (observation 4) is piecewise constant: a value drawn uniformly
    from [-1, 1] m/s, held for a duration drawn uniformly from 2-5 s, then the
    next, all from the episode's seed. The reward's velocity term scores the
    axle's true forward velocity against it: standing still earns 0.01 a
    step (for staying up) where tracking earns up to 0.1.

    `bbbench/VelocityTracking-v0` is the same task under the first reward (kept for
    comparability: it ranks falling at once above standing off target).

    Everything shared by the suite is documented in `BalanceEnv`.
    """


@_with_version_history
class NoisySensorsEnv(_TaskEnv):
    """`bbbench/NoisySensors-v1`: velocity tracking with a real robot's sensors.

    VelocityTracking's ground and targets, observed through a biased, noisy
    IMU and noisy encoders (the tutorial's noisy variant, now reproducible):

    | Reading     | Per-episode bias   | Per-step noise (std) |
    |-------------|--------------------|----------------------|
    | pitch       | N(0, 0.1) rad      | 0.05 rad             |
    | pitch_rate  | none               | 0.01 rad/s           |
    | wheel_speed | none               | 0.05 rad/s           |

    Bias and noise are drawn from the episode's seed; the wheel command and
    the target are observed exactly. The reward uses the true state.

    `bbbench/NoisySensors-v0` is the same task under the first reward (kept for
    comparability: it ranks falling at once above standing off target).

    Everything shared by the suite is documented in `BalanceEnv`.
    """


_TERRAIN_V1 = """
    ## Why -v1 (Bumps, Obstacles, Slopes)

    The -v0 terrain had no headroom: the PD baseline never fell on it, so it
    ranked policies by velocity tracking alone. The -v1 terrain is designed
    from the robot's own numbers. A wheel of radius r = 0.1 m driven by servos
    of at most 0.6 N m each (1.2 N m for the 1 kg bot, a force of 12 N at the
    ground) climbs slopes far steeper than 25 deg at rest: the lean it needs
    there, about 0.2 rad, is well inside the 1 rad fall limit. So at walking
    pace (-v0's 0.2-0.8 m/s) PD stalls against a hill or step that is too much
    and rocks back, without falling (measured: no fall on 45 deg hills). A bot
    falls when the wheels are stopped or lifted while the torso's momentum
    carries on: the -v1 tasks ask for 1-2 m/s (40-80% of the 2.46 m/s top
    speed, which PD holds on flat ground on every seed tested), and build the
    ground on cells fine enough to have edges (a heightfield joins nodes by
    ramps one cell long). Each task's default difficulty is calibrated so that
    the PD baseline finishes 20-60% of the evaluation episodes (the table is
    in docs/tasks.md, from `python bench/bench_calibration.py`).

    The strip starts 1 m behind the bot and reaches 23 m ahead on Bumps and
    Obstacles (PD got at most 16.5 m in 60 episodes), 31 m on Slopes (2 m/s
    for 15 s fits), with flat ground beyond its ends. The bot cannot steer,
    and terrain turns it: on a wide strip PD drifted 2 m sideways in half the
    episodes and 7-14 m in one in ten. So the -v1 terrain has no side edge: it
    repeats across the strip with a period of 1.2 m (Bumps, Obstacles) or
    1.6 m (Slopes), the strip is two periods wide, and the field is moved by
    whole periods to stay under the bot (the ground under the bot does not
    change). The start pad is a level band across the strip.
"""


def _terrain_v1(cls: type[BalanceEnv]) -> type[BalanceEnv]:
    """Append the design of the -v1 terrain, shared by its three tasks, to the docstring."""
    cls.__doc__ = f"{cls.__doc__.rstrip()}\n{_TERRAIN_V1}"
    return cls


@_with_version_history
@_terrain_v1
class BumpsEnv(_TaskEnv):
    """`bbbench/Bumps-v2`: cross short, steep random hills at speed.

    The ground is a strip of random hills (white noise low-passed by a Gaussian
    of 0.1 m, on 0.05 m cells), a new one from each episode's seed, with flat
    ground around it. The bot starts on a level pad 3 m from the strip's near
    end and must drive along it: the target velocity is drawn from [1, 2] m/s
    and held 2-5 s at a time. Sensors are perfect.

    `difficulty` (default 0.9, any number in [0, 1]) sets the hills' height,
    0.01 m + 0.10 m x difficulty, and with it their steepest slope: about
    2 deg at 0, 13 deg at 0.5, 21 deg at 0.9 (the default) and 23 deg at 1
    (the mean over seeds of each map's steepest node). Hills of 0.1 m
    features are shorter than the 0.24 m between the wheels: at 1-2 m/s the
    wheels meet each one as a kick, not a climb, and the kicks lift them off
    the ground and turn the bot. The value is recorded in `env.spec.kwargs`
    and changes the task's fingerprint.

    `bbbench/Bumps-v1` is the same task under the first reward. `bbbench/Bumps-v0`
    (kept for comparability): an 8 x 20 m
    strip of smooth hills (0.35 m features, 0.2 m cells), 0.02 m high at
    difficulty 0 and 0.08 m at 1 (default 0.3), at 0.2-0.8 m/s.

    Everything shared by the suite is documented in `BalanceEnv`.
    """


@_with_version_history
@_terrain_v1
class ObstaclesEnv(_TaskEnv):
    """`bbbench/Obstacles-v2`: cross an obstacle course of boxes and steps at speed.

    Along a strip of level ground on 0.05 m cells, obstacles follow one another,
    a new course from each episode's seed (`ObstacleCourse`): 40% are
    full-width steps (a raised band 0.1-0.8 m deep: up, then down), the rest
    boxes 0.3-1.2 m across and 0.1-0.8 m deep (repeating across the strip
    with the terrain). The bot cannot steer: a box under one wheel turns it.
    Targets and start as in Bumps.

    `difficulty` (default 0.5, in [0, 1]) sets the obstacles' height, each
    25-100% of 0.01 m + 0.05 m x difficulty (at 1: 0.06 m, 0.6x the wheel
    radius, a face the wheel can climb only with momentum), and their spacing:
    the gap before each is drawn from [0.3, 2.0 - 1.7 x difficulty] m, so at
    difficulty 1 the next obstacle comes within 0.15-0.3 s at speed, before
    the bot has recovered from the last (no flat run-up).

    `bbbench/Obstacles-v1` is the same task under the first reward.
    `bbbench/Obstacles-v0` (kept for comparability): an
    8 x 20 m strip on 0.2 m cells with scattered boxes and steps, 0.015-0.05 m
    high (default difficulty 0.3), at 0.2-0.8 m/s.

    Everything shared by the suite is documented in `BalanceEnv`.
    """


@_with_version_history
@_terrain_v1
class SlopesEnv(_TaskEnv):
    """`bbbench/Slopes-v2`: climb and descend ramps at speed.

    A strip on 0.1 m cells, level across and ramped along the driving
    direction: ramps 0.3-1.5 m long, each inclined up or down by an angle drawn
    up to 0.5 rad x difficulty, heights kept within [0, 2] m (a ramp that would
    leave them levels off), a new profile from each episode's seed (`Slopes`).
    Targets and start as in Bumps: the command asks for 1-2 m/s up and down.

    `difficulty` (default 0.9, in [0, 1]) sets the steepest ramp: 0 at 0,
    14 deg at 0.5, 26 deg at 0.9 (the default), 29 deg at 1. Holding a
    speed on a ramp needs a lean into it (about 0.2 rad at 20 deg for this
    bot's 1.57 N m/rad of torso weight torque); the kink where an up-ramp
    meets a down-ramp changes that lean at once, and at 2 m/s the wheels leave
    the crest. On ramps of at most 20 deg (difficulty 0.7) PD finishes about
    two thirds of the episodes, too many for the calibration: the default is
    steeper than that.

    `bbbench/Slopes-v1` is the same task under the first reward (kept for
    comparability: it ranks falling at once above standing off target).

    Everything shared by the suite is documented in `BalanceEnv`.
    """


TASK_ENVS: dict[str, type[BalanceEnv]] = {
    cls.__name__: cls
    for cls in (
        FlatBalanceEnv,
        VelocityTrackingEnv,
        NoisySensorsEnv,
        BumpsEnv,
        ObstaclesEnv,
        SlopesEnv,
    )
}
