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

from bbbench.tasks.balance import BalanceEnv
from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import SUITE, task_name


def _with_version_history(cls: type[BalanceEnv]) -> type[BalanceEnv]:
    """Append the Version History of every version of the class's task to its docstring."""
    name = cls.__name__.removesuffix("Env")
    versions = [spec for task_id, spec in SUITE.items() if task_name(task_id) == name]
    if not versions:
        raise LookupError(f"{cls.__name__} plays no task of the suite (no bbbench/{name}-vN)")
    newest = max(versions, key=lambda spec: int(spec.id.rsplit("-v", 1)[1]))
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
    """`bbbench/FlatBalance-v0`: stay upright and in place on flat ground.

    The tutorial's task. The target velocity is 0 throughout, the sensors are
    perfect, and the ground is an endless plane with the tutorial's friction.
    A policy that stands still scores close to the maximum return, 150.

    Everything shared by the suite (actions, observations, reward, starting
    state, episode end, keyword arguments) is documented in `BalanceEnv`.
    """


@_with_version_history
class VelocityTrackingEnv(_TaskEnv):
    """`bbbench/VelocityTracking-v0`: follow a target velocity that changes.

    Flat ground and perfect sensors, as in FlatBalance. The target forward
    velocity (observation 4) is piecewise constant: a value drawn uniformly
    from [-1, 1] m/s, held for a duration drawn uniformly from 2-5 s, then the
    next, all from the episode's seed. The reward's velocity term scores the
    axle's true forward velocity against it, so standing still loses up to
    0.1 per step.

    Everything shared by the suite is documented in `BalanceEnv`.
    """


@_with_version_history
class NoisySensorsEnv(_TaskEnv):
    """`bbbench/NoisySensors-v0`: velocity tracking with a real robot's sensors.

    VelocityTracking's ground and targets, observed through a biased, noisy
    IMU and noisy encoders (the tutorial's noisy variant, now reproducible):

    | Reading     | Per-episode bias   | Per-step noise (std) |
    |-------------|--------------------|----------------------|
    | pitch       | N(0, 0.1) rad      | 0.05 rad             |
    | pitch_rate  | none               | 0.01 rad/s           |
    | wheel_speed | none               | 0.05 rad/s           |

    Bias and noise are drawn from the episode's seed; the wheel command and
    the target are observed exactly. The reward uses the true state.

    Everything shared by the suite is documented in `BalanceEnv`.
    """


@_with_version_history
class BumpsEnv(_TaskEnv):
    """`bbbench/Bumps-v0`: drive forward across smooth random hills.

    The ground is an 8 x 20 m strip of smooth hills (low-passed noise on
    0.2 m cells), a new one from each episode's seed, with flat ground around
    it. The bot starts on a level pad 3 m from the strip's near end and must
    drive along it: the target velocity is drawn from [0.2, 0.8] m/s and held
    2-5 s at a time. Sensors are perfect.

    `difficulty` (default 0.3, any number in [0, 1]) sets the hills' height:
    0.02 m at 0, 0.08 m at 1 (the wheel radius is 0.1 m). The value is
    recorded in `env.spec.kwargs` and changes the task's fingerprint.

    Everything shared by the suite is documented in `BalanceEnv`.
    """


@_with_version_history
class ObstaclesEnv(_TaskEnv):
    """`bbbench/Obstacles-v0`: drive forward over scattered boxes and steps.

    Like Bumps, on an 8 x 20 m strip of level ground with boxes (0.2-0.8 m
    across) and full-width steps (0.3-1.5 m deep) raised on it, a new layout
    from each episode's seed. The bot cannot steer: a box under one wheel
    turns it, and it may leave the strip's side for the flat ground around.

    `difficulty` (default 0.3, in [0, 1]) sets the obstacles' height, up to
    0.015 m at 0 and 0.05 m at 1 (each obstacle 25-100% of that), and their
    number, 0.15 to 0.3 boxes per square metre.

    Everything shared by the suite is documented in `BalanceEnv`.
    """


TASK_ENVS: dict[str, type[BalanceEnv]] = {
    cls.__name__: cls
    for cls in (FlatBalanceEnv, VelocityTrackingEnv, NoisySensorsEnv, BumpsEnv, ObstaclesEnv)
}
