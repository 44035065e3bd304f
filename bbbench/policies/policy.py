"""What `bbbench eval` needs of a policy, and the actors policies hand out.

A `Policy` says which tasks it fits and gives, per task, an *actor*: a
picklable callable from a batch of observations, shape (k, n) (the bots of a
multi-bot task, or episodes played in lockstep), and optionally one random
generator per row, to a list of k actions (None where the policy's output is
NaN). Generators are given when the policy acts stochastically; each is seeded
from its episode's seed, so every episode is reproducible wherever it runs.
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from bbbench.policies.errors import PolicyError
from bbbench.policies.normalization import ObservationNormalization
from bbbench.robots import ROBOTS
from bbbench.tasks.group import team_robot
from bbbench.tasks.suite import list_tasks, spec

Actor = Callable[[np.ndarray, "Sequence[np.random.Generator] | None"], list]


def describe_space(space: spaces.Space) -> str:
    """'Box(17,)', 'Discrete(9)' or 'Box(-1.0, 1.0, (1,))': short, for error messages."""
    if isinstance(space, spaces.Discrete):
        return f"Discrete({space.n})"
    if isinstance(space, spaces.Box) and space.shape == (1,):
        return f"Box({float(space.low[0])}, {float(space.high[0])}, (1,))"
    return f"Box{space.shape}"


class Policy(abc.ABC):
    """A policy `bbbench eval` can score."""

    name: str  # as the user gave it: a built-in name or a file name
    algorithm: str  # "PPO", ..., or the built-in's own name
    action_mode: str  # the env action mode it plays: "discrete" or "continuous"
    sha256: str | None = None  # of the policy file; None for a built-in without one
    random_actions = False  # True: acts from the episode's generator even when deterministic
    # Why it cannot sample actions (`--stochastic`); None: it has a distribution to sample.
    deterministic_only: str | None = "a classical controller has no distribution to sample"
    normalization_source: str | None = None  # where load_policy found statistics on its own
    height_scan = False  # True: observes the ground ahead too (tasks played with height_scan)
    robot: str | None = None  # the robot whose tasks it plays (`bbbench.robots`); None: any

    def mismatch(self, task_id: str) -> str | None:
        """Why the policy cannot play `task_id` (its spaces), or None if it can."""
        return None

    @abc.abstractmethod
    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        """A picklable actor for one bot of `task_id`."""

    def acting(self, task_id: str, stochastic: bool = False) -> Actor:
        """`actor`, sampling the policy's distribution if `stochastic`: `PolicyError` for
        a policy that has none (its episodes would be labelled sampled, yet be the
        deterministic ones)."""
        if stochastic and not self.random_actions and self.deterministic_only is not None:
            raise PolicyError(
                f"{self.name}: it acts deterministically only ({self.deterministic_only}): "
                f"drop --stochastic"
            )
        return self.actor(task_id, deterministic=not stochastic)

    def env_options(self) -> dict[str, Any]:
        """Keywords for a single-bot env to observe what the policy expects."""
        return {"height_scan": True} if self.height_scan else {}

    def spaces_text(self) -> str:
        """The spaces the policy works in, for error messages."""
        if self.robot is None:  # any robot's tasks, in its action mode
            return f"any robot, any observation -> {self.action_mode} actions"
        robot = ROBOTS[self.robot]
        action_space = robot.action_space(self.action_mode)
        return f"{robot.name} robot, any observation -> {describe_space(action_space)}"

    def record(self) -> dict[str, Any]:
        """The policy as the results JSON records it."""
        return {
            "name": self.name,
            "source": "file" if self.sha256 else "builtin",
            "sha256": self.sha256,
            "algorithm": self.algorithm,
            "action_mode": self.action_mode,
        }


@dataclasses.dataclass(frozen=True)
class PDActor:
    """A classical controller (PD, LQR) on each row of a batch."""

    controller: Any

    def __call__(self, observations: np.ndarray, rngs=None) -> list:
        return [self.controller(row) for row in observations]


@dataclasses.dataclass(frozen=True, eq=False)
class TeamActor:
    """A mixed team's actor (`TaskSpec.robots`): one actor per robot, each called once a
    step on a batch of its robot's live bots (the agent groups BenchMARL trains a policy
    each for). Bot i plays robots[i % len(robots)], as `TaskSpec.robots` says, at any
    team size. A play loop calls `team`, not the actor."""

    actors: dict[str, Actor]  # robot name: the actor of its bots
    robots: tuple[str, ...]  # the task's `robots`

    def team(self, rows: Sequence[np.ndarray], bots: Sequence[int], rngs=None) -> list:
        """The actions of the live bots `bots` (indices), observing `rows` (each bot's own
        width), in their order; `rngs`, one per row, for actors that act at random."""
        actions: list = [None] * len(rows)
        for name, actor in self.actors.items():
            mine = [k for k, bot in enumerate(bots) if team_robot(self.robots, bot) == name]
            if mine:
                batch = np.stack([rows[k] for k in mine])
                acted = actor(batch, None if rngs is None else [rngs[k] for k in mine])
                for k, action in zip(mine, acted, strict=True):
                    actions[k] = action
        return actions

    def __call__(self, observations: np.ndarray, rngs=None) -> list:
        raise TypeError(
            "a mixed team's actor acts through team(rows, bots, rngs): its bots observe in "
            "their own robots' widths"
        )


@dataclasses.dataclass(frozen=True)
class RandomActor:
    """Uniform actions, each row's from its episode's generator."""

    space: spaces.Space

    def __call__(self, observations: np.ndarray, rngs: Sequence[np.random.Generator]) -> list:
        if isinstance(self.space, spaces.Discrete):
            return [int(rng.integers(self.space.n)) for rng in rngs]
        low, high = self.space.low, self.space.high
        return [rng.uniform(low, high).astype(np.float32) for rng in rngs]


@dataclasses.dataclass(frozen=True)
class ConstantActor:
    """The same action on every row."""

    action: Any

    def __call__(self, observations: np.ndarray, rngs=None) -> list:
        return [self.action] * len(observations)


@dataclasses.dataclass(frozen=True, eq=False)
class NormalizedActor:
    """An actor that sees observations as VecNormalize showed them in training."""

    actor: Actor
    normalization: ObservationNormalization

    def __call__(self, observations: np.ndarray, rngs=None) -> list:
        return self.actor(self.normalization(observations), rngs)


@dataclasses.dataclass(frozen=True, eq=False)
class TorchActor:
    """stable-baselines3's own policy module acting, through its `predict` (which
    samples from torch's global generator when asked for stochastic actions)."""

    policy: Any

    def __call__(self, observations: np.ndarray, rngs=None) -> list:
        actions, _ = self.policy.predict(observations, deterministic=rngs is None)
        if isinstance(self.policy.action_space, spaces.Discrete):
            return [int(a) for a in actions]
        return list(actions)


def mixed_mismatch(policy: Policy, task_id: str) -> str:
    """Why a policy of one robot's bots cannot play a mixed team's task."""
    task = spec(task_id)
    return (
        f"{task_id} plays a mixed team of {' and '.join(task.robots)} robots, each in its own "
        f"spaces; {policy.name} plays one robot's bots"
    )


def act_once(actor: Actor, observation: np.ndarray, rng: np.random.Generator | None = None):
    """One observation's action (None if the policy's output is NaN)."""
    return actor(observation[None], None if rng is None else [rng])[0]


def fitting_tasks(policy: Policy) -> list[str]:
    """The latest version of each task of the suite that the policy can play."""
    return [task_id for task_id in list_tasks(latest=True) if policy.mismatch(task_id) is None]
