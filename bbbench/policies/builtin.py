"""The classical baselines and reference policies every task can be scored against:
PD, stand (PD holding 0 m/s), LQR, random and zero."""

from __future__ import annotations

import numpy as np

from bbbench.policies.lqr import LQRController
from bbbench.policies.pd import PDController
from bbbench.policies.policy import Actor, ConstantActor, PDActor, Policy, RandomActor
from bbbench.tasks.actions import WHEEL_SPEED_CHANGES
from bbbench.tasks.suite import agent_spaces


class PDPolicy(Policy):
    """The PD baseline (`bbbench.policies.PDController`): reads only the shared layout, so
    it fits every task."""

    name = algorithm = "pd"
    hold_velocity: float | None = None  # m/s held instead of the task's target; None tracks it

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        return PDActor(PDController(action_mode=self.action_mode, hold_velocity=self.hold_velocity))


class StandPolicy(PDPolicy):
    """The PD baseline holding target velocity 0 whatever the task asks: it stays up and
    does not drive, so its score is what a task pays for staying up alone. On
    FlatBalance, whose target is 0, it is the PD baseline itself."""

    name = algorithm = "stand"
    hold_velocity = 0.0


class LQRPolicy(Policy):
    """The LQR baseline (`bbbench.policies.lqr.LQRController`): designed from a model
    identified from the simulator; reads only the shared layout, so it fits every task."""

    name = algorithm = "lqr"

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        return PDActor(LQRController(action_mode=self.action_mode))


class RandomPolicy(Policy):
    """Uniformly random actions: the 0 of the normalized score. It always acts
    stochastically, from the episode's seeded generator."""

    name = algorithm = "random"
    random_actions = True

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        return RandomActor(agent_spaces(task_id, self.action_mode)[1])


class ZeroPolicy(Policy):
    """Never change the wheel command: the bot is left to fall (a lower bound)."""

    name = algorithm = "zero"

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        if self.action_mode == "discrete":
            return ConstantActor(WHEEL_SPEED_CHANGES.index(0.0))
        return ConstantActor(np.zeros(1, dtype=np.float32))
