"""Sensor models: what the bot's IMU and encoders report, against the true state.

The reward always uses the true state; only the observation is affected.
"""

from __future__ import annotations

import numpy as np

from bbbench.parameters import parameters

SENSED = ("pitch", "pitch_rate", "wheel_speed")  # the readings a sensor model may corrupt


@parameters
class PerfectSensors:
    """Readings equal the true state, with no delay."""

    delay_steps: int = 0

    def episode_errors(self, rng: np.random.Generator, n_steps: int) -> None:
        return None


@parameters
class NoisySensors:
    """A per-episode bias plus per-step Gaussian noise on pitch, pitch rate and wheel speed.

    Standard deviations are in the readings' units (rad, rad/s, rad/s). The
    defaults are the tutorial's noisy variant: pitch bias N(0, 0.1) rad, per-step
    sigma 0.05 rad on pitch, 0.01 rad/s on the gyro, 0.05 rad/s on wheel speed.
    `delay_steps` (0 or 1) reports the previous step's readings.
    """

    bias_std: tuple[float, float, float] = (0.1, 0.0, 0.0)
    noise_std: tuple[float, float, float] = (0.05, 0.01, 0.05)
    delay_steps: int = 0

    def __post_init__(self) -> None:
        for name in ("bias_std", "noise_std"):
            if len(getattr(self, name)) != len(SENSED):
                raise ValueError(
                    f"{name} takes one standard deviation per reading {SENSED}, "
                    f"got {getattr(self, name)!r}"
                )
        if any(not s >= 0 for s in (*self.bias_std, *self.noise_std)):
            raise ValueError(f"standard deviations must be >= 0, got {self!r}")
        if self.delay_steps not in (0, 1):
            raise ValueError(f"delay_steps must be 0 or 1, got {self.delay_steps!r}")

    def episode_errors(self, rng: np.random.Generator, n_steps: int) -> list[tuple]:
        """Each step's (pitch, pitch rate, wheel speed) error, bias included: steps 0..n_steps."""
        bias = rng.normal(0.0, self.bias_std)
        noise = rng.normal(0.0, self.noise_std, size=(n_steps + 1, len(SENSED)))
        return [tuple(row) for row in (bias + noise).tolist()]


SensorModel = PerfectSensors | NoisySensors
