"""Perturbations: reset-time components of a task that change the robot or its world.

A perturbation is a frozen component of the `TaskSpec` (`TaskSpec.perturbations`), made
from one keyword argument of the env (`gym.make(id, payload_mass=0.5)`). At every reset
`Scene` calls each one's `apply(bots, rng)` once, after the episode's draws and before
the bots are placed: `bots` are the scene's `BalanceBot`s, `rng` the episode's own
perturbation stream (`SeedStreams.perturbation`, a stream of its own, so that the
draws of every other stream are unchanged). `apply` sets absolute values, so applying
it again at the next reset changes nothing that the last one set.

A task keeps only the perturbations that are not at their default: a keyword given at
its default makes the very same task, and so the same fingerprint. A task without
perturbations behaves as it did before they existed (tests/test_perturbations.py).

Adding a perturbation is one component here, with its keyword in `PERTURBATIONS`, and
its test.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from bbbench.parameters import parameters


def _number(keyword: str, value: Any, low: float, high: float, what: str) -> float:
    """`value` as a float in [low, high], or the error that says what is expected."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ValueError(f"{keyword} must be a number ({what}), got {value!r}")
    if not low <= value <= high:
        raise ValueError(f"{keyword} must be in [{low:g}, {high:g}] ({what}), got {value!r}")
    return float(value)


@parameters
class PayloadMass:
    """`payload_mass`: kg added to the torso at its centre of mass (the bot weighs 1 kg)."""

    kg: float = 0.0

    def __post_init__(self) -> None:
        _number("payload_mass", self.kg, 0.0, 10.0, "kg added to the torso")

    @property
    def default(self) -> bool:
        return self.kg == 0.0

    def apply(self, bots: Sequence[Any], rng: np.random.Generator) -> None:
        for bot in bots:
            bot.set_payload(self.kg)


@parameters
class MotorStrength:
    """`motor_strength`: a multiplier on the wheel servos' torque limit."""

    factor: float = 1.0

    def __post_init__(self) -> None:
        _number("motor_strength", self.factor, 0.05, 10.0, "times the servos' torque limit")

    @property
    def default(self) -> bool:
        return self.factor == 1.0

    def apply(self, bots: Sequence[Any], rng: np.random.Generator) -> None:
        for bot in bots:
            bot.set_motor_strength(self.factor)


# Each perturbation's env keyword, and how a value of it becomes the component.
PERTURBATIONS = {
    "payload_mass": PayloadMass,
    "motor_strength": MotorStrength,
}


def perturbation(keyword: str, value: Any):
    """The component the env keyword `keyword` asks for with `value`."""
    return PERTURBATIONS[keyword](value)
