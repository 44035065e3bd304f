"""What `bbbench eval` needs of a policy, and the registry of built-in policies.

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
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from bbbench.tasks.suite import agent_spaces, list_tasks

Actor = Callable[[np.ndarray, "Sequence[np.random.Generator] | None"], list]


class PolicyError(ValueError):
    """A policy that cannot be evaluated: a missing, unreadable or unsupported file, or a
    policy that fits no task. The CLI reports it in one line with exit code 2."""


class RefusedForSafety(PolicyError):
    """A submitted file refused unread, because reading it could run its code."""

    def __init__(self, message: str) -> None:
        super().__init__(f"refused for safety: {message}")


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

    def mismatch(self, task_id: str) -> str | None:
        """Why the policy cannot play `task_id` (its spaces), or None if it can."""
        return None

    @abc.abstractmethod
    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        """A picklable actor for one bot of `task_id`."""

    def spaces_text(self) -> str:
        """The spaces the policy works in, for error messages."""
        action_space = agent_spaces(list_tasks()[0], self.action_mode)[1]
        return f"any observation -> {describe_space(action_space)}"

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
    """The PD baseline on each row of a batch."""

    controller: Any

    def __call__(self, observations: np.ndarray, rngs=None) -> list:
        return [self.controller(row) for row in observations]


@dataclasses.dataclass(frozen=True)
class RandomActor:
    """Uniform actions, each row's from its episode's generator."""

    space: spaces.Space

    def __call__(self, observations: np.ndarray, rngs: Sequence[np.random.Generator]) -> list:
        if isinstance(self.space, spaces.Discrete):
            return [int(rng.integers(self.space.n)) for rng in rngs]
        low, high = self.space.low, self.space.high
        return [rng.uniform(low, high).astype(np.float32) for rng in rngs]


class PDPolicy(Policy):
    """The PD baseline (`bbbench.policies.PDController`): reads only the shared layout, so
    it fits every task."""

    name = algorithm = "pd"

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        from bbbench.policies.pd import PDController

        return PDActor(PDController(action_mode=self.action_mode))


class RandomPolicy(Policy):
    """Uniformly random actions: the 0 of the normalized score. It always acts
    stochastically, from the episode's seeded generator."""

    name = algorithm = "random"
    random_actions = True

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        return RandomActor(agent_spaces(task_id, self.action_mode)[1])


class SB3ZipPolicy(Policy):
    """A stable-baselines3 `.zip`, read without unpickling (`bbbench.policies.sb3`).

    Its actor runs the network in numpy (`backend="numpy"`, the default: faster
    for small MLPs) or as stable-baselines3's own torch module (`"torch"`).
    """

    def __init__(self, path: str | Path, backend: str = "numpy") -> None:
        from bbbench.policies.sb3 import read_sb3_zip

        if backend not in ("numpy", "torch"):
            raise ValueError(f"backend must be 'numpy' or 'torch', got {backend!r}")
        self.loaded = loaded = read_sb3_zip(path)
        self.name = loaded.name
        self.sha256 = loaded.sha256
        self.algorithm = loaded.algorithm
        self.action_mode = loaded.action_mode
        self.backend = backend
        self._actors: dict[tuple, Actor] = {}

    def mismatch(self, task_id: str) -> str | None:
        observation_space, action_space = agent_spaces(task_id, self.action_mode)
        policy_action = self.loaded.action_space
        if observation_space.shape == self.loaded.observation_shape and (
            describe_space(action_space) == describe_space(policy_action)
        ):
            return None
        return (
            f"{task_id} wants {describe_space(observation_space)} -> "
            f"{describe_space(agent_spaces(task_id, 'discrete')[1])} or "
            f"{describe_space(agent_spaces(task_id, 'continuous')[1])}"
        )

    def spaces_text(self) -> str:
        return f"Box{self.loaded.observation_shape} -> {describe_space(self.loaded.action_space)}"

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        observation_space, action_space = agent_spaces(task_id, self.action_mode)
        key = (observation_space.shape, describe_space(action_space), self.backend)
        if key not in self._actors:
            if self.backend == "numpy":
                self._actors[key] = self.loaded.actor(observation_space, action_space)
            else:
                self._actors[key] = TorchActor(
                    self.loaded.torch_policy(observation_space, action_space)
                )
        return self._actors[key]


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


def act_once(actor: Actor, observation: np.ndarray, rng: np.random.Generator | None = None):
    """One observation's action (None if the policy's output is NaN)."""
    return actor(observation[None], None if rng is None else [rng])[0]


def _reference() -> Policy:
    return SB3ZipPolicy(REFERENCE_POLICY)


REFERENCE_POLICY = Path(__file__).with_name("reference.zip")

# Built-in policies by name. A new classical baseline registers here (or through
# `register_policy`) and `bbbench eval NAME` scores it.
BUILTIN_POLICIES: dict[str, Callable[[], Policy]] = {
    "pd": PDPolicy,
    "random": RandomPolicy,
    "reference": _reference,
}


def register_policy(name: str, factory: Callable[[], Policy]) -> None:
    """Make `bbbench eval NAME` score the policy `factory()` returns."""
    if name in BUILTIN_POLICIES:
        raise ValueError(f"a built-in policy is already called {name!r}")
    BUILTIN_POLICIES[name] = factory


def load_policy(name_or_path: str | Path, backend: str = "numpy") -> Policy:
    """A built-in policy by name, or a stable-baselines3 `.zip` by path."""
    text = str(name_or_path)
    if text in BUILTIN_POLICIES:
        return BUILTIN_POLICIES[text]()
    path = Path(text)
    if path.suffix.lower() == ".zip" or path.exists():
        return SB3ZipPolicy(path, backend=backend)
    raise PolicyError(
        f"unknown policy {text!r}: give a stable-baselines3 .zip file or a built-in policy, "
        f"one of {', '.join(sorted(BUILTIN_POLICIES))}"
    )


def fitting_tasks(policy: Policy) -> list[str]:
    """The suite's tasks the policy can play."""
    return [task_id for task_id in list_tasks() if policy.mismatch(task_id) is None]
