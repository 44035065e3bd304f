"""Command schedules: the forward velocity a task asks for at each control step.

A schedule is a frozen description; `targets()` draws one episode's targets
from the episode's generator, so `reset(seed=...)` decides them.
"""

from __future__ import annotations

import numpy as np

from bbbench.parameters import parameters


def _check_speed(name: str, value: float) -> None:
    if not np.isfinite(value):
        raise ValueError(f"{name} must be a finite speed in m/s, got {value!r}")


@parameters
class ConstantVelocity:
    """The same target forward velocity (m/s) for the whole episode."""

    velocity: float = 0.0

    def __post_init__(self) -> None:
        _check_speed("velocity", self.velocity)

    @property
    def top_target(self) -> float:
        """The fastest target (m/s, either way) the schedule can ask for."""
        return abs(self.velocity)

    def targets(self, rng: np.random.Generator, n_steps: int, dt: float) -> list[float]:
        """Targets for steps 0..n_steps (the observation after reset, then after each step)."""
        return [float(self.velocity)] * (n_steps + 1)


@parameters
class PiecewiseConstantVelocity:
    """Targets drawn uniformly from [low, high] m/s, each held for U(hold) seconds."""

    low: float = -1.0
    high: float = 1.0
    hold: tuple[float, float] = (2.0, 5.0)  # s

    def __post_init__(self) -> None:
        _check_speed("low", self.low)
        _check_speed("high", self.high)
        if not (self.low <= self.high and 0 < self.hold[0] <= self.hold[1]):
            raise ValueError(
                f"need low <= high and 0 < hold[0] <= hold[1], got low={self.low!r}, "
                f"high={self.high!r}, hold={self.hold!r}"
            )

    @property
    def top_target(self) -> float:
        """The fastest target (m/s, either way) the schedule can ask for."""
        return max(abs(self.low), abs(self.high))

    def targets(self, rng: np.random.Generator, n_steps: int, dt: float) -> list[float]:
        targets: list[float] = []
        while len(targets) <= n_steps:
            steps = max(1, round(rng.uniform(*self.hold) / dt))
            targets.extend([float(rng.uniform(self.low, self.high))] * steps)
        return targets[: n_steps + 1]


@parameters
class PiecewiseConstantTwist:
    """A forward velocity drawn uniformly from [low, high] m/s and a yaw rate from
    [yaw_low, yaw_high] rad/s (+ turning left), each pair held for U(hold) seconds:
    legged_gym's velocity command for a robot that cannot move sideways. Its targets are
    (velocity, yaw rate) pairs; `targets` of a steering task's scenario reads them."""

    low: float = -1.0
    high: float = 1.0
    yaw_low: float = -1.0
    yaw_high: float = 1.0
    hold: tuple[float, float] = (2.0, 5.0)  # s

    def __post_init__(self) -> None:
        for name in ("low", "high", "yaw_low", "yaw_high"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be a finite number, got {getattr(self, name)!r}")
        if not (
            self.low <= self.high
            and self.yaw_low <= self.yaw_high
            and 0 < self.hold[0] <= self.hold[1]
        ):
            raise ValueError(
                f"need low <= high, yaw_low <= yaw_high and 0 < hold[0] <= hold[1], got "
                f"low={self.low!r}, high={self.high!r}, yaw_low={self.yaw_low!r}, "
                f"yaw_high={self.yaw_high!r}, hold={self.hold!r}"
            )

    @property
    def top_target(self) -> float:
        """The fastest forward target (m/s, either way) the schedule can ask for."""
        return max(abs(self.low), abs(self.high))

    def targets(
        self, rng: np.random.Generator, n_steps: int, dt: float
    ) -> list[tuple[float, float]]:
        """(velocity, yaw rate) for steps 0..n_steps: each pair drawn (velocity first),
        then held for a duration drawn from `hold`."""
        targets: list[tuple[float, float]] = []
        while len(targets) <= n_steps:
            steps = max(1, round(rng.uniform(*self.hold) / dt))
            pair = (float(rng.uniform(self.low, self.high)),
                    float(rng.uniform(self.yaw_low, self.yaw_high)))  # fmt: skip
            targets.extend([pair] * steps)
        return targets[: n_steps + 1]


CommandSchedule = ConstantVelocity | PiecewiseConstantVelocity | PiecewiseConstantTwist

# The schedules the suite's tasks share, each new value held 2-5 s.
# Either way on flat ground (VelocityTracking, NoisySensors).
VELOCITY_TARGETS = PiecewiseConstantVelocity(low=-1.0, high=1.0, hold=(2.0, 5.0))
# On terrain the bot must make progress across it: forward targets only (the -v0 terrain,
# the crossings).
FORWARD_TARGETS = PiecewiseConstantVelocity(low=0.2, high=0.8, hold=(2.0, 5.0))
# The -v1 terrain: crossed at speed. Why: docs/notebook.md, "The terrain: why -v0 had no
# headroom, and what -v1 changes".
SPEED_TARGETS = PiecewiseConstantVelocity(low=1.0, high=2.0, hold=(2.0, 5.0))
