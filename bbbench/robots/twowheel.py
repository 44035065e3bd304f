"""The two-wheel robot's face to its tasks: its action table and observation layout.

An action changes the commanded wheel speed (rad/s); the command is then held
by the wheels' velocity servos and clamped to the wheel-speed limit. The
observation is the five shared values (`bbbench.robots.layout`) and nothing more.
The body is `BalanceBot` (`bbbench.robots.balancebot`).
"""

from __future__ import annotations

import operator
from collections.abc import Callable
from typing import Any

import numpy as np
from gymnasium import spaces
from pybullet_utils.bullet_client import BulletClient

from bbbench.robots.balancebot import MODEL, BalanceBot, BotState
from bbbench.robots.layout import (
    ObservationField,
    observe,
    observe_scanned,
    sensed,
    shared_layout,
)
from bbbench.robots.robot import Robot

# The tutorial's nine changes of commanded wheel speed, rad/s per control step.
WHEEL_SPEED_CHANGES = (-1.0, -0.5, -0.2, -0.01, 0.0, 0.01, 0.2, 0.5, 1.0)
# Continuous actions in [-1, 1] are scaled to the same largest change.
MAX_WHEEL_SPEED_CHANGE = max(abs(change) for change in WHEEL_SPEED_CHANGES)

ACTION_MODES = ("discrete", "continuous")


def action_space(action_mode: str) -> spaces.Space:
    """The action space of `action_mode` ("discrete" or "continuous")."""
    if action_mode == "discrete":
        return spaces.Discrete(len(WHEEL_SPEED_CHANGES))
    if action_mode == "continuous":
        return spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
    raise ValueError(f"action_mode must be one of {ACTION_MODES}, got {action_mode!r}")


def discrete_change(action) -> float:
    """The wheel-speed change (rad/s) of a discrete action index, or a clear ValueError."""
    try:
        index = operator.index(action)
    except TypeError:
        index = -1  # not an integer (a float, a NaN, an array of several values)
    if 0 <= index < len(WHEEL_SPEED_CHANGES):
        return WHEEL_SPEED_CHANGES[index]
    raise ValueError(
        f"discrete action {action!r} is not in the action space: expected an integer index "
        f"0..{len(WHEEL_SPEED_CHANGES) - 1} into the wheel-speed changes "
        f"{WHEEL_SPEED_CHANGES} rad/s"
    )


def continuous_change(action) -> float:
    """The wheel-speed change (rad/s) of a continuous action in [-1, 1], or a clear ValueError."""
    if type(action) is np.ndarray and action.shape == (1,):
        value = float(action[0])
    else:
        try:
            value = float(np.asarray(action, dtype=np.float64).reshape(1)[0])
        except (TypeError, ValueError):
            value = float("nan")
    # NaN fails both comparisons: it is refused, never clamped.
    if -1.0 <= value <= 1.0:
        return value * MAX_WHEEL_SPEED_CHANGE
    raise ValueError(
        f"continuous action {action!r} is not in the action space: expected one finite "
        f"number in [-1, 1] (scaled to a wheel-speed change of at most "
        f"{MAX_WHEEL_SPEED_CHANGE} rad/s), shape (1,)"
    )


OBSERVATION_LAYOUT = shared_layout(MODEL.wheel_speed_limit, MODEL.top_speed)


class TwoWheel(Robot):
    """The tutorial's balancing bot: a torso on two wheels on one axle (`BalanceBot`)."""

    name = "two-wheel"
    controller = "pd"  # bbbench.policies.controllers.pd
    summary = "the tutorial's two-wheeled balancing bot (1.0 kg, 0.5 m tall)"
    model = MODEL
    action_modes = ACTION_MODES

    def body(self, client: BulletClient) -> BalanceBot:
        return BalanceBot(client)

    def action_space(self, action_mode: str) -> spaces.Space:
        return action_space(action_mode)

    def action_decoder(self, action_mode: str) -> Callable[[Any], float]:
        self.check_action_mode(action_mode)
        return discrete_change if action_mode == "discrete" else continuous_change

    def own_layout(self) -> tuple[ObservationField, ...]:
        return OBSERVATION_LAYOUT

    def task_interface(self) -> str:
        return (
            "The robot's actions and observation are in docs/robots.md; the task's page "
            "(docs/environments/) gives them with its reward, starting state, episode end "
            "and keywords; `BalanceEnv` documents the API."
        )

    def actions_markdown(self) -> str:
        table = [
            "| Num | Change of commanded wheel speed (rad/s) |",
            "|-----|-----------------------------------------|",
            *(f"| {i} | {change:g} |" for i, change in enumerate(WHEEL_SPEED_CHANGES)),
        ]
        return (
            f'`action_mode="discrete"` (default): `Discrete({len(WHEEL_SPEED_CHANGES)})`, '
            "a change of the commanded wheel speed per step (the tutorial's table). "
            '`action_mode="continuous"`: `Box(-1, 1, (1,), float32)`, scaled to a change '
            f"of -{MAX_WHEEL_SPEED_CHANGE:g} to {MAX_WHEEL_SPEED_CHANGE:g} rad/s. The "
            f"command is clamped to +-{MODEL.wheel_speed_limit:g} rad/s.\n\n" + "\n".join(table)
        )

    def observe(
        self,
        reading: tuple[float, float, float],
        command: float,
        target: float,
        state: BotState,
        scan: list[float] | None = None,
    ) -> np.ndarray:
        if scan is None:
            return observe(*reading, command, target)
        return observe_scanned(*reading, command, target, scan)

    def values(
        self, reading: tuple[float, float, float], command: float, target: float, state: BotState
    ) -> tuple[float, ...]:
        return (*sensed(*reading), command, target)


TWO_WHEEL = TwoWheel()
