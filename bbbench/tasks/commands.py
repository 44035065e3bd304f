"""Command schedules: the forward velocity a task asks for at each control step.

A schedule is a frozen description; `targets()` draws one episode's targets
from the episode's generator, so `reset(seed=...)` decides them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bbbench.robots import MODEL


@dataclass(frozen=True)
class ConstantVelocity:
    """The same target forward velocity (m/s) for the whole episode."""

    velocity: float = 0.0

    def __post_init__(self) -> None:
        if not abs(self.velocity) <= MODEL.top_speed:
            raise ValueError(
                f"target velocity must be within the bot's top speed "
                f"+-{MODEL.top_speed:g} m/s, got {self.velocity!r}"
            )

    def targets(self, rng: np.random.Generator, n_steps: int) -> list[float]:
        """Targets for steps 0..n_steps (observation after reset, then after each step)."""
        del rng  # nothing random to draw
        return [float(self.velocity)] * (n_steps + 1)
