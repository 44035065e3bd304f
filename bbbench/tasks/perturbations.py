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

Adding a perturbation is one component here, listed in `PERTURBATIONS`, and its test (a
`RobotSetting` when it sets one value on each bot).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from bbbench.parameters import parameters


class RobotSetting:
    """A perturbation that sets one value on every bot at each reset: its single field,
    checked to lie in [`low`, `high`], passed to the bot's method `setter`."""

    keyword: ClassVar[str]  # its env keyword
    meaning: ClassVar[str]  # what its value is, for error messages
    low: ClassVar[float]
    high: ClassVar[float]
    setter: ClassVar[str]  # the BalanceBot method that sets it

    @property
    def value(self) -> float:
        return getattr(self, dataclasses.fields(self)[0].name)

    def __post_init__(self) -> None:
        value, where = self.value, f"{self.keyword} must be"
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise ValueError(f"{where} a number ({self.meaning}), got {value!r}")
        if not self.low <= value <= self.high:
            raise ValueError(
                f"{where} in [{self.low:g}, {self.high:g}] ({self.meaning}), got {value!r}"
            )

    @property
    def default(self) -> bool:
        """Whether it leaves the bot as built (the field's default)."""
        return self.value == dataclasses.fields(self)[0].default

    def apply(self, bots: Sequence[Any], rng: np.random.Generator) -> None:
        for bot in bots:
            getattr(bot, self.setter)(self.value)


@parameters
class PayloadMass(RobotSetting):
    """`payload_mass`: kg added to the torso at its centre of mass (the bot weighs 1 kg)."""

    kg: float = 0.0
    keyword = "payload_mass"
    meaning = "kg added to the torso"
    low, high = 0.0, 10.0
    setter = "set_payload"


@parameters
class MotorStrength(RobotSetting):
    """`motor_strength`: a multiplier on the wheel servos' torque limit."""

    factor: float = 1.0
    keyword = "motor_strength"
    meaning = "times the servos' torque limit"
    low, high = 0.05, 10.0
    setter = "set_motor_strength"


# Each perturbation by its env keyword: `PERTURBATIONS[keyword](value)` is the component.
PERTURBATIONS = {kind.keyword: kind for kind in (PayloadMass, MotorStrength)}
