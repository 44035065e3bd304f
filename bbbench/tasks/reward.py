"""The shared reward: one component per version of it, each used by every task of its
generation, and the step's outcome (reward, fall, info) computed once for both env APIs.

`StayUpReward` (FlatBalance-v1, VelocityTracking-v1, NoisySensors-v1, Bumps-v2,
Obstacles-v2, Slopes-v2, MultiBalance-v1, MultiBumps-v1), in dm_control's
`rewards.tolerance` style: each step earns between 0 and 0.1,

    upright  = tolerance(|pitch|, bound 0.1 rad, width 0.5 rad)
    near     = tolerance(|velocity_error|, bound 0.1 m/s, width 0.25 m/s)
    toward   = ramp(|velocity_error|, bound 0.1 m/s, width 2.0 m/s)
    tracking = 0.9 * near + 0.1 * toward
    reward   = 0.1 * upright * (0.1 + 0.9 * tracking)

where velocity_error = forward_velocity - target_velocity, tolerance(x, bound, width) is 1
for x <= bound, falls as 1 - ((x - bound) / width)^2 and is 0 from x = bound + width on,
and ramp(x, bound, width) is the same with a linear fall, 1 - (x - bound) / width: a long
tail. The two terms `info`
reports are 0.01 * upright (staying up) and 0.09 * upright * tracking (doing the task).
Staying up never costs: no step of a bot that is up earns less than 0, so a fall only
forfeits the rest of the episode. The tail pays a bot far from its target for moving
towards it (1 m/s short of a 1.5 m/s target earns more than standing), so the way from
standing to driving is uphill. The numbers were chosen by measurement (docs/tasks.md,
"The shared reward": random < stand < PD on every task).

`RewardWeights` (every v0 task and the -v1 terrain), the tutorial's form:

    reward = 0.1 * (1 - |pitch|) - 0.1 * |forward_velocity - target_velocity|

at most 0.1 per step, but negative whenever the bot is 1 m/s or more off its target:
there a bot held back by terrain scored less for staying up than for falling at once.
It stays, unchanged, for the versions that published it.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from bbbench.parameters import parameters
from bbbench.robots import FALL_TILT, BotState


def tolerance(x: float, bound: float, width: float) -> float:
    """1 for |x| <= bound, 1 - ((|x| - bound) / width)^2 beyond it, 0 from bound + width on.

    Plain float arithmetic (no transcendental function), so the same bits on every CPU.
    """
    excess = abs(x) - bound
    if excess <= 0.0:
        return 1.0
    if excess >= width:
        return 0.0
    ratio = excess / width
    return 1.0 - ratio * ratio


def ramp(x: float, bound: float, width: float) -> float:
    """1 for |x| <= bound, 1 - (|x| - bound) / width beyond it, 0 from bound + width on:
    `tolerance` with a linear fall, for a long tail."""
    excess = abs(x) - bound
    if excess <= 0.0:
        return 1.0
    if excess >= width:
        return 0.0
    return 1.0 - excess / width


@parameters
class StayUpReward:
    """The shared reward from FlatBalance-v1 on: in [0, scale] every step, so staying up
    never costs (the module's docstring has the formula)."""

    scale: float = 0.1  # the most one step earns: upright and on target
    upright_share: float = 0.1  # of `scale`, earned for being upright whatever the velocity
    pitch_bound: float = 0.1  # rad: upright up to this lean
    pitch_width: float = 0.5  # rad: the upright credit is 0 from pitch_bound + this on
    velocity_bound: float = 0.1  # m/s: on target up to this velocity error
    velocity_width: float = 0.25  # m/s: the narrow credit is 0 from velocity_bound + this on
    # Of the tracking credit, the share paid by a linear tail that reaches 0 only at
    # velocity_bound + tail_width m/s off target: a bot standing far from its target
    # gains by moving towards it, long before it is near enough for the narrow credit.
    tail_share: float = 0.1
    tail_width: float = 2.0  # m/s: the tail is 0 from velocity_bound + this on

    def __post_init__(self) -> None:
        for name in ("scale", "pitch_bound", "velocity_bound"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        for name in ("pitch_width", "velocity_width", "tail_width"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("upright_share", "tail_share"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)!r}")
        # Read once per step: one attribute, not six (benchmarks/bench_core.py times the cost).
        constants = (
            self.scale,
            self.upright_share,
            self.pitch_bound,
            self.pitch_width,
            self.velocity_bound,
            self.velocity_width,
            self.tail_share,
            self.tail_width,
        )
        object.__setattr__(self, "_constants", constants)

    @property
    def max_step(self) -> float:
        """The most one step earns."""
        return self.scale

    def formula(self) -> str:
        """The step's reward with this reward's numbers, as the docs print it."""
        tail = self.tail_share
        return (
            f"upright  = tolerance(|pitch|, {self.pitch_bound:g} rad, {self.pitch_width:g} rad)\n"
            f"near     = tolerance(|velocity error|, {self.velocity_bound:g} m/s, "
            f"{self.velocity_width:g} m/s)\n"
            f"toward   = ramp(|velocity error|, {self.velocity_bound:g} m/s, "
            f"{self.tail_width:g} m/s)\n"
            f"tracking = {1 - tail:g} * near + {tail:g} * toward\n"
            f"reward   = {self.scale:g} * upright * ({self.upright_share:g} + "
            f"{1 - self.upright_share:g} * tracking)"
        )

    def terms(self, pitch: float, velocity_error: float) -> tuple[float, float]:
        """(upright, velocity): the credit for staying up, and for tracking the target
        while up. Both lie in [0, scale]; their sum is the step's reward."""
        scale, share, pitch_bound, pitch_width, bound, width, tail, tail_width = self._constants
        upright = scale * tolerance(pitch, pitch_bound, pitch_width)
        tracking = (1.0 - tail) * tolerance(velocity_error, bound, width) + tail * ramp(
            velocity_error, bound, tail_width
        )
        return upright * share, upright * (1.0 - share) * tracking


def stay_up_history(earlier: tuple[str, ...], version: int) -> tuple[str, ...]:
    """The version history of a task's version `version` that moved to `StayUpReward`,
    the version before it (`earlier`, its history) otherwise unchanged."""
    change = (
        f"v{version}: the shared reward in which staying up never costs (StayUpReward: each "
        f"step earns 0-0.1, 0.01 for being upright and up to 0.09 more for tracking the "
        f"target velocity; docs/tasks.md says why); robot, dynamics, terrain, commands, "
        f"sensors and evaluation seeds as v{version - 1}."
    )
    return (*earlier, change)


@parameters
class RewardWeights:
    """The first shared reward (v0 tasks, -v1 terrain): the weights of its two terms. Its
    class name is part of those tasks' fingerprints."""

    upright: float = 0.1  # reward per step when perfectly upright; also the per-step maximum
    velocity: float = 0.1  # penalty per m/s of forward-velocity error

    def __post_init__(self) -> None:
        for name in ("upright", "velocity"):
            value = getattr(self, name)
            if not value >= 0:
                raise ValueError(f"reward weight {name!r} must be >= 0, got {value!r}")

    @property
    def max_step(self) -> float:
        """The most one step earns."""
        return self.upright

    def formula(self) -> str:
        """The step's reward with these weights, as the docs print it."""
        return f"reward = {self.upright:g} * (1 - |pitch|) - {self.velocity:g} * |velocity error|"

    def terms(self, pitch: float, velocity_error: float) -> tuple[float, float]:
        """(upright, velocity): 0.1 * (1 - |pitch|) and -0.1 * |velocity error|."""
        return self.upright * (1.0 - abs(pitch)), -self.velocity * velocity_error


@parameters
class TwistReward:
    """The shared reward's form for a commanded forward velocity and yaw rate (the
    steering tasks): in [0, scale] every step, so staying up never costs.

        upright  = tolerance(|pitch|, pitch_bound, pitch_width)
        forward  = 0.9 * tolerance(|v error|, velocity_bound, velocity_width)
                   + 0.1 * ramp(|v error|, velocity_bound, tail_width)
        turning  = 0.9 * tolerance(|yaw rate error|, yaw_rate_bound, yaw_rate_width)
                   + 0.1 * ramp(|yaw rate error|, yaw_rate_bound, yaw_rate_tail_width)
        tracking = (1 - yaw_share) * forward + yaw_share * turning
        reward   = scale * upright * (upright_share + (1 - upright_share) * tracking)

    `StayUpReward` with a second tracked term, each with its own tolerance and tail, as
    legged_gym rewards each commanded velocity."""

    scale: float = 0.1
    upright_share: float = 0.1
    pitch_bound: float = 0.1  # rad
    pitch_width: float = 0.5  # rad
    velocity_bound: float = 0.1  # m/s
    velocity_width: float = 0.25  # m/s
    tail_share: float = 0.1  # of each tracked term, its long linear tail's share
    tail_width: float = 2.0  # m/s
    yaw_rate_bound: float = 0.1  # rad/s
    yaw_rate_width: float = 0.5  # rad/s
    yaw_rate_tail_width: float = 2.0  # rad/s
    yaw_share: float = 0.5  # of the tracking credit, the yaw rate's

    def __post_init__(self) -> None:
        for name in ("scale", "pitch_bound", "velocity_bound", "yaw_rate_bound"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        widths = ("pitch_width", "velocity_width", "tail_width", "yaw_rate_width")
        for name in (*widths, "yaw_rate_tail_width"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("upright_share", "tail_share", "yaw_share"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)!r}")
        # Read once per step: one attribute, not twelve (as StayUpReward's).
        constants = tuple(getattr(self, field.name) for field in dataclasses.fields(self))
        object.__setattr__(self, "_constants", constants)

    @property
    def max_step(self) -> float:
        return self.scale

    def formula(self) -> str:
        """The step's reward with this reward's numbers, as the docs print it."""
        tail, yaw = self.tail_share, self.yaw_share
        return (
            f"upright  = tolerance(|pitch|, {self.pitch_bound:g} rad, {self.pitch_width:g} rad)\n"
            f"forward  = {1 - tail:g} * tolerance(|v error|, {self.velocity_bound:g} m/s, "
            f"{self.velocity_width:g} m/s)\n"
            f"           + {tail:g} * ramp(|v error|, {self.velocity_bound:g} m/s, "
            f"{self.tail_width:g} m/s)\n"
            f"turning  = {1 - tail:g} * tolerance(|yaw rate error|, {self.yaw_rate_bound:g} "
            f"rad/s, {self.yaw_rate_width:g} rad/s)\n"
            f"           + {tail:g} * ramp(|yaw rate error|, {self.yaw_rate_bound:g} rad/s, "
            f"{self.yaw_rate_tail_width:g} rad/s)\n"
            f"tracking = {1 - yaw:g} * forward + {yaw:g} * turning\n"
            f"reward   = {self.scale:g} * upright * ({self.upright_share:g} + "
            f"{1 - self.upright_share:g} * tracking)"
        )

    def terms(
        self, pitch: float, velocity_error: float, yaw_rate_error: float
    ) -> tuple[float, float]:
        """(upright, tracking): the credit for staying up, and for tracking both targets
        while up. Both lie in [0, scale]; their sum is the step's reward."""
        (scale, share, pitch_bound, pitch_width, velocity_bound, velocity_width, tail,
         tail_width, yaw_bound, yaw_width, yaw_tail_width, yaw_share) = self._constants  # fmt: skip
        upright = scale * tolerance(pitch, pitch_bound, pitch_width)
        forward = (1.0 - tail) * tolerance(
            velocity_error, velocity_bound, velocity_width
        ) + tail * ramp(velocity_error, velocity_bound, tail_width)
        turning = (1.0 - tail) * tolerance(yaw_rate_error, yaw_bound, yaw_width) + tail * ramp(
            yaw_rate_error, yaw_bound, yaw_tail_width
        )
        tracking = (1.0 - yaw_share) * forward + yaw_share * turning
        return upright * share, upright * (1.0 - share) * tracking


Reward = StayUpReward | RewardWeights | TwistReward


def has_fallen(state: BotState) -> bool:
    """Whether the torso has tilted past `FALL_TILT` (1 rad) from vertical: the episode's
    termination, on every task."""
    return state.tilt > FALL_TILT


def step_outcome(
    state: BotState, target: float, reward: Reward
) -> tuple[float, bool, dict[str, Any]]:
    """One bot's step, judged by the task's rules: its reward, whether it fell, and its
    `info` (the reward's two terms, `reward_upright` and `reward_velocity`, and
    `velocity_error`, |forward_velocity - target_velocity| in m/s, true, not sensed).

    Both env APIs call this, so the rules are written once.
    """
    velocity_error = abs(state.forward_velocity - target)
    upright, velocity = reward.terms(state.pitch, velocity_error)
    info = {
        "reward_upright": upright,
        "reward_velocity": velocity,
        "velocity_error": velocity_error,
    }
    return upright + velocity, has_fallen(state), info


def twist_outcome(
    state: Any, target: tuple[float, float], reward: TwistReward
) -> tuple[float, bool, dict[str, Any]]:
    """`step_outcome` for a commanded (velocity, yaw rate): the reward, whether the bot
    fell, and its `info`: the two terms, `velocity_error` (m/s) and `yaw_rate_error`
    (rad/s), each |true - target|."""
    velocity, yaw_rate = target
    velocity_error = abs(state.forward_velocity - velocity)
    yaw_rate_error = abs(state.yaw_rate - yaw_rate)
    upright, tracking = reward.terms(state.pitch, velocity_error, yaw_rate_error)
    info = {
        "reward_upright": upright,
        "reward_velocity": tracking,
        "velocity_error": velocity_error,
        "yaw_rate_error": yaw_rate_error,
    }
    return upright + tracking, has_fallen(state), info
