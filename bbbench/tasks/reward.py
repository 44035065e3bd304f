"""The shared base reward: one function, used by every task.

    reward = upright * (1 - |pitch|) - velocity * |forward_velocity - target_velocity|

with pitch in rad and velocities in m/s. It keeps the tutorial's form (an
upright term and a velocity-error term); the tutorial's 0.01 per rad/s of
wheel-speed error is 0.1 per m/s of forward-velocity error on 0.1 m wheels.
With the default weights a step earns at most 0.1 (upright, on target), so a
1500-step episode scores at most 150.
"""

from __future__ import annotations

from bbbench.parameters import parameters


@parameters
class RewardWeights:
    """Weights of the base reward's two terms."""

    upright: float = 0.1  # reward per step when perfectly upright; also the per-step maximum
    velocity: float = 0.1  # penalty per m/s of forward-velocity error

    def __post_init__(self) -> None:
        for name in ("upright", "velocity"):
            value = getattr(self, name)
            if not value >= 0:
                raise ValueError(f"reward weight {name!r} must be >= 0, got {value!r}")


def reward_terms(pitch, velocity_error, weights: RewardWeights):
    """The base reward's two terms, (upright, velocity); the reward is their sum, at most
    `weights.upright`. `velocity_error` is |forward_velocity - target_velocity| in m/s
    (the envs report it in their info, with the two terms).

    Floats give floats; numpy arrays (one value per bot) give arrays.
    """
    return weights.upright * (1.0 - abs(pitch)), -weights.velocity * velocity_error
