"""Perturbations: reset-time components of a task that change the robot or its world.

A perturbation is a frozen component of the `TaskSpec` (`TaskSpec.perturbations`), made
from one keyword argument of the env (`gym.make(id, payload_mass=0.5)`). At every reset
`Scene` calls each one's `apply(scene, rng)` once, after the episode's draws and before
the bots are placed: `scene` gives its bots, its ground, the episode's sensor errors and
its schedule of pushes, `rng` is the episode's own perturbation stream
(`SeedStreams.perturbation`, a stream of its own, so that the draws of every other
stream are unchanged). `apply` sets absolute values, so applying it again at the next
reset changes nothing that the last one set. What acts during the episode (a delayed
command, a push) is set up here and costs the step loop one comparison.

A task keeps only the perturbations that are not at their default: a keyword given at
its default makes the very same task, and so the same fingerprint. A task without
perturbations behaves as it did before they existed (tests/test_perturbations.py).

The axes, their units, ranges and the reasons for the standard grids are tabled in the
single-bot env's docstring (`bbbench.envs.balance.BalanceEnv`) and the robustness guide
(docs/guides/robustness.md).

Adding a perturbation is one component here, listed in `PERTURBATIONS`, and its test (a
`RobotSetting` when it sets one value on each bot).
"""

from __future__ import annotations

import dataclasses
import math
import textwrap
from typing import Any, ClassVar

import numpy as np

from bbbench.parameters import is_real, parameters
from bbbench.robots.body import Body
from bbbench.tasks.sensors import NoisySensors, PerfectSensors

# Seconds between two pushes: each waits U(2, 4) s after the last (the first, after the
# start), as legged_gym pushes its robots at random intervals.
PUSH_INTERVAL = (2.0, 4.0)


class Perturbation:
    """A component with one field, the value of its env keyword, checked to lie in
    [`low`, `high`] (`(low`: above `low`), a whole number when `whole`."""

    keyword: ClassVar[str]  # its env keyword
    meaning: ClassVar[str]  # what its value is, for error messages
    low: ClassVar[float]
    high: ClassVar[float]
    low_open: ClassVar[bool] = False  # `low` itself is refused
    whole: ClassVar[bool] = False  # a count of steps
    unit: ClassVar[str]  # for the table of axes
    # The values `bbbench sweep` and the board's robustness profile play, and why.
    grid: ClassVar[tuple[float, ...]]
    reason: ClassVar[str]
    # It changes what the sensors read: single-bot tasks only. A multi-bot task's sensors
    # are its own (MultiNoisySensors-v0's), and the board's multi-bot profiles have no
    # sensor axis.
    observed: ClassVar[bool] = False

    @property
    def value(self) -> float:
        return getattr(self, dataclasses.fields(self)[0].name)

    def __post_init__(self) -> None:
        value, where = self.value, f"{self.keyword} must be"
        kind = "a whole number" if self.whole else "a number"
        if not is_real(value) or not math.isfinite(value) or (self.whole and value != int(value)):
            raise ValueError(f"{where} {kind} ({self.meaning}), got {value!r}")
        if not (self.low < value if self.low_open else self.low <= value) or value > self.high:
            bracket = "(" if self.low_open else "["
            raise ValueError(
                f"{where} in {bracket}{self.low:g}, {self.high:g}] ({self.meaning}), got {value!r}"
            )
        # One spelling per value (1 and 1.0 make the same task, and the same fingerprint).
        name = dataclasses.fields(self)[0].name
        object.__setattr__(self, name, int(value) if self.whole else float(value))

    def leaves_as_built(self, task: Any) -> bool:
        """Whether it leaves `task` as built (for most, every field at its default): such
        a component is not kept in the spec."""
        return self == type(self)()

    def apply(self, scene: Any, rng: np.random.Generator) -> None:
        """Set the perturbation on `scene` for the episode starting."""
        raise NotImplementedError


class RobotSetting(Perturbation):
    """A perturbation that sets its value on every bot, through one of the perturbation
    hooks every body declares (`bbbench.robots.body.Body`): `set_on`."""

    def apply(self, scene: Any, rng: np.random.Generator) -> None:
        for bot in scene.bots:
            self.set_on(bot, self.value)

    @staticmethod
    def set_on(bot: Body, value: Any) -> None:
        """Call the body's hook for the perturbation with `value`."""
        raise NotImplementedError


@parameters
class PayloadMass(RobotSetting):
    """`payload_mass`: kg added to the torso at its centre of mass (the bot weighs 1 kg),
    or to what the task's scenario carries (`Scenario.set_payload`: BeamCarry's beam)."""

    kg: float = 0.0
    keyword = "payload_mass"
    meaning = "kg added to the torso"
    low, high = 0.0, 10.0
    unit = "kg on the torso"
    grid = (0.0, 1.0, 2.0, 3.0, 4.0)
    reason = (
        "up to four times the 1 kg bot: over 0-1 kg no policy measured lost score; PPO "
        "falls from 2 kg on, PD from 8"
    )

    def apply(self, scene: Any, rng: np.random.Generator) -> None:
        scene.scenario.set_payload(scene, self.kg)


@parameters
class ComOffset(RobotSetting):
    """`com_offset`: the torso's centre of mass moved forward (m; negative: backward).
    Its mass and inertia are unchanged; the readings stay those of the torso as built."""

    metres: float = 0.0
    keyword = "com_offset"
    meaning = "m the torso's centre of mass moves forward"
    low, high = -0.2, 0.2
    unit = "m, centre of mass forward"
    grid = (-0.05, -0.025, 0.0, 0.025, 0.05)
    reason = "legged_gym's and Isaac Lab's ±5 cm; at 2.5 cm PD keeps a quarter of its score"

    @staticmethod
    def set_on(bot: Body, value: float) -> None:
        bot.set_com_offset(value)


@parameters
class MotorStrength(RobotSetting):
    """`motor_strength`: a multiplier on the wheel servos' torque limit."""

    factor: float = 1.0
    keyword = "motor_strength"
    meaning = "times the servos' torque limit"
    low, high, low_open = 0.0, 10.0, True
    unit = "times the servos' torque limit"
    grid = (0.1, 0.2, 0.5, 0.8, 1.2)
    reason = (
        "down to a tenth: over 0.5-1.2 no policy measured lost score; PPO falls at 0.2, "
        "PD and LQR at 0.1"
    )

    @staticmethod
    def set_on(bot: Body, value: float) -> None:
        bot.set_motor_strength(value)


@parameters
class ActionDelay(RobotSetting):
    """`action_delay`: control steps between a wheel-speed command and the servos acting
    on it. The observation's wheel command is the one asked for; the servos hold the
    one asked for `steps` steps before (0 rad/s for the first `steps` of an episode)."""

    steps: int = 0
    keyword = "action_delay"
    meaning = "control steps between a command and the servos"
    low, high, whole = 0, 100, True
    unit = "control steps of 10 ms"
    grid = (0, 1, 2, 3, 5)
    reason = "the real-world RL suite's 3-9 steps; PPO falls from 2 on, PD from 15"

    @staticmethod
    def set_on(bot: Body, value: int) -> None:
        bot.set_action_delay(value)


@parameters
class Friction(Perturbation):
    """`friction`: a multiplier on the ground's lateral friction (and so the wheels' grip)."""

    factor: float = 1.0
    keyword = "friction"
    meaning = "times the ground's lateral friction"
    low, high, low_open = 0.0, 10.0, True
    unit = "times the ground's friction"
    grid = (0.2, 0.3, 0.5, 1.0, 1.5)
    reason = "legged_gym's 0.1-2 about the 0.8 grip as built; below 0.5 the wheels slip"

    def apply(self, scene: Any, rng: np.random.Generator) -> None:
        scene.ground.set_friction(self.factor)


@parameters
class SensorNoise(Perturbation):
    """`sensor_noise`: a multiplier on the sensors' bias and noise. On a task with perfect
    sensors it scales `NoisySensors`' defaults (the tutorial's noise), drawn from the
    perturbation stream; on a task with noisy sensors, the task's own errors."""

    factor: float = 0.0  # as built on perfect sensors; 1 is as built on noisy ones
    keyword = "sensor_noise"
    meaning = "times the sensors' bias and noise"
    low, high = 0.0, 10.0
    unit = "times the sensors' noise"
    grid = (0.0, 0.5, 1.0, 2.0, 3.0)
    observed = True
    reason = (
        "1 is the tutorial's noise (NoisySensors', and on perfect sensors the same), 3 about "
        "the real-world RL suite's largest"
    )

    def leaves_as_built(self, task: Any) -> bool:
        return self.factor == (0.0 if isinstance(task.sensors, PerfectSensors) else 1.0)

    def apply(self, scene: Any, rng: np.random.Generator) -> None:
        errors = scene.sensor_errors
        if errors is None:
            errors = NoisySensors().episode_errors(rng, scene.task.max_episode_steps)
        f = self.factor
        scene.sensor_errors = [(f * a, f * b, f * c) for a, b, c in errors]


@parameters
class Push(Perturbation):
    """`push`: N s, a horizontal impulse on the torso, forward or back with equal odds,
    every `PUSH_INTERVAL` s (each bot its own times and directions). With `growth`, each
    push is `growth` N s stronger per second of the episode (PushRecovery's shoves); the
    `push` keyword sets `impulse`, the first push's, and keeps the task's growth."""

    impulse: float = 0.0
    growth: float = 0.0  # N s per s of the episode
    keyword = "push"
    meaning = "N s pushing the torso every 2-4 s"
    low, high = 0.0, 10.0
    unit = "N s every 2-4 s"
    grid = (0.0, 0.25, 0.5, 0.75, 1.0)
    reason = "1 N s changes the 1 kg bot's speed by about 1 m/s; at 2 N s every policy falls"

    def __post_init__(self) -> None:
        super().__post_init__()
        growth = self.growth
        if not is_real(growth) or not growth >= 0:
            raise ValueError(f"push growth must be a number >= 0 (N s per s), got {growth!r}")
        object.__setattr__(self, "growth", float(growth))

    def apply(self, scene: Any, rng: np.random.Generator) -> None:
        dt, steps = scene.task.control_dt, scene.task.max_episode_steps
        for index in range(len(scene.bots)):
            when = rng.uniform(*PUSH_INTERVAL)
            while (step := round(when / dt)) < steps:
                size = self.impulse + self.growth * step * dt
                scene.schedule_push(step, index, size * rng.choice((-1.0, 1.0)))
                when += rng.uniform(*PUSH_INTERVAL)


# Each perturbation by its env keyword: `PERTURBATIONS[keyword](value)` is the component.
PERTURBATIONS = {
    kind.keyword: kind
    for kind in (PayloadMass, ComOffset, Friction, MotorStrength, ActionDelay, SensorNoise, Push)
}


def refusal(keyword: str, task: Any) -> str | None:
    """Why the perturbation `keyword` does not apply to `task`, or None if it does."""
    if PERTURBATIONS[keyword].observed and task.multi_agent:
        return (
            f"{keyword} does not apply to {task.id}: a multi-bot task's sensors are its own "
            "(sensor perturbations apply to single-bot tasks only)"
        )
    takes = task.scenario_class.perturbations
    if takes is not None and keyword not in takes:
        return f"{keyword} does not apply to {task.id}: it takes {', '.join(takes)}"
    return None


def unit(keyword: str, task: Any = None) -> str:
    """The unit of `keyword`'s values, on `task` if given (its scenario may apply it
    elsewhere: BeamCarry's `payload_mass` loads the beam, not the torsos)."""
    own = task.scenario_class.units.get(keyword) if task is not None else None
    return own or PERTURBATIONS[keyword].unit


def axes_markdown() -> str:
    """The table of the axes, and why each grid: the robustness guide and `BalanceEnv`'s
    docstring hold it verbatim (tests/test_perturbations.py)."""
    rows = [
        "| keyword | unit | default | accepted | standard grid |",
        "|---|---|---|---|---|",
    ]
    for keyword, kind in PERTURBATIONS.items():
        default = "0 or 1" if kind is SensorNoise else f"{dataclasses.fields(kind)[0].default:g}"
        accepted = f"{'(' if kind.low_open else '['}{kind.low:g}, {kind.high:g}]"
        grid = ", ".join(f"{value:g}" for value in kind.grid)
        rows.append(f"| `{keyword}` | {kind.unit} | {default} | {accepted} | {grid} |")
    reasons = [
        textwrap.fill(f"- `{keyword}`: {kind.reason}.", 88, subsequent_indent="  ")
        for keyword, kind in PERTURBATIONS.items()
    ]
    return "\n".join([*rows, "", *reasons])
