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
import functools
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from bbbench.policies.errors import PolicyError
from bbbench.policies.vecnormalize import ObservationNormalization
from bbbench.tasks.observation import observation_space as single_bot_observation_space
from bbbench.tasks.suite import agent_spaces, list_tasks

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
    normalization_source: str | None = None  # where load_policy found statistics on its own
    height_scan = False  # True: observes the ground ahead too (tasks played with height_scan)

    def mismatch(self, task_id: str) -> str | None:
        """Why the policy cannot play `task_id` (its spaces), or None if it can."""
        return None

    @abc.abstractmethod
    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        """A picklable actor for one bot of `task_id`."""

    def env_options(self) -> dict[str, Any]:
        """Keywords for a single-bot env to observe what the policy expects."""
        return {"height_scan": True} if self.height_scan else {}

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
    """A classical controller (PD, LQR) on each row of a batch."""

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
    hold_velocity: float | None = None  # m/s held instead of the task's target; None tracks it

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        from bbbench.policies.pd import PDController

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
        from bbbench.policies.lqr import LQRController

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


@dataclasses.dataclass(frozen=True)
class ConstantActor:
    """The same action on every row."""

    action: Any

    def __call__(self, observations: np.ndarray, rngs=None) -> list:
        return [self.action] * len(observations)


class ZeroPolicy(Policy):
    """Never change the wheel command: the bot is left to fall (a lower bound)."""

    name = algorithm = "zero"

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        from bbbench.tasks.actions import WHEEL_SPEED_CHANGES

        if self.action_mode == "discrete":
            return ConstantActor(WHEEL_SPEED_CHANGES.index(0.0))
        return ConstantActor(np.zeros(1, dtype=np.float32))


class SB3ZipPolicy(Policy):
    """A stable-baselines3 `.zip`, read without unpickling (`bbbench.policies.sb3`).

    Its actor runs the network in numpy (`backend="numpy"`, the default: faster
    for small MLPs) or as stable-baselines3's own torch module (`"torch"`).
    `normalization`: the `VecNormalize` statistics the policy was trained with
    (`bbbench.policies.vecnormalize`), applied to every observation first.
    """

    def __init__(
        self,
        path: str | Path,
        backend: str = "numpy",
        normalization: ObservationNormalization | None = None,
    ) -> None:
        from bbbench.policies.sb3 import read_sb3_zip

        if backend not in ("numpy", "torch"):
            raise ValueError(f"backend must be 'numpy' or 'torch', got {backend!r}")
        self.loaded = loaded = read_sb3_zip(path)
        self.name = loaded.name
        self.sha256 = loaded.sha256
        self.algorithm = loaded.algorithm
        self.action_mode = loaded.action_mode
        self.backend = backend
        self.normalization = normalization
        # The single-bot layout followed by the height scan: the tasks are played with it.
        self.height_scan = (
            loaded.observation_shape == single_bot_observation_space(height_scan=True).shape
        )
        self._actors: dict[tuple, Actor] = {}

    def mismatch(self, task_id: str) -> str | None:
        observation_space, action_space = agent_spaces(task_id, self.action_mode, self.height_scan)
        policy_action = self.loaded.action_space
        if observation_space.shape == self.loaded.observation_shape and (
            describe_space(action_space) == describe_space(policy_action)
        ):
            return None
        blind = agent_spaces(task_id, "discrete")[0]
        scanned = agent_spaces(task_id, "discrete", height_scan=True)[0]
        with_scan = (
            f" (or {describe_space(scanned)} with height_scan=True)"
            if scanned.shape != blind.shape
            else ""
        )
        return (
            f"{task_id} wants {describe_space(blind)}{with_scan} -> "
            f"{describe_space(agent_spaces(task_id, 'discrete')[1])} or "
            f"{describe_space(agent_spaces(task_id, 'continuous')[1])}"
        )

    def spaces_text(self) -> str:
        return f"Box{self.loaded.observation_shape} -> {describe_space(self.loaded.action_space)}"

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        if not deterministic and self.loaded.use_sde:
            raise PolicyError(
                f"{self.name}: trained with gSDE (use_sde=True), whose exploration noise is "
                f"not saved in the zip: bbbench evaluates it deterministically only (drop "
                f"--stochastic)"
            )
        observation_space, action_space = agent_spaces(task_id, self.action_mode, self.height_scan)
        key = (observation_space.shape, describe_space(action_space), self.backend)
        if key not in self._actors:
            if self.backend == "numpy":
                actor = self.loaded.actor(observation_space, action_space)
            else:
                actor = TorchActor(self.loaded.torch_policy(observation_space, action_space))
            if self.normalization is not None:
                actor = NormalizedActor(actor, self.normalization)
            self._actors[key] = actor
        return self._actors[key]

    def record(self) -> dict[str, Any]:
        record = super().record()
        if self.normalization is not None:
            record["observation_normalization"] = self.normalization.record()
        return record


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


def act_once(actor: Actor, observation: np.ndarray, rng: np.random.Generator | None = None):
    """One observation's action (None if the policy's output is NaN)."""
    return actor(observation[None], None if rng is None else [rng])[0]


def _reference() -> Policy:
    return SB3ZipPolicy(REFERENCE_POLICY)


# PPO with stable-baselines3's defaults (64 x 64 tanh MLP, n_steps 2048, batch 64, learning
# rate 3e-4), discrete actions, 4 envs of VelocityTracking-v0, 400,000 steps, seed 0:
# PPO("MlpPolicy", make_vec_env("bbbench/VelocityTracking-v0", n_envs=4, seed=0), seed=0,
# device="cpu").learn(400_000). Kept byte for byte as the default of `bbbench eval`; the
# recipes of `bbbench train` (bbbench/training/recipes/) train the baselines now.
REFERENCE_POLICY = Path(__file__).with_name("reference.zip")
# PPO policies trained on the -v1 terrain tasks, 1M steps each (docs/tasks.md): the
# evidence that learning pays there, shipped so that it is re-scored byte for byte.
TERRAIN_POLICIES = {
    f"ppo-{name}-v1": Path(__file__).with_name(f"ppo-{name}-v1.zip")
    for name in ("bumps", "obstacles", "slopes")
}

# Built-in policies by name. A new classical baseline registers here (or through
# `register_policy`) and `bbbench eval NAME` scores it.
BUILTIN_POLICIES: dict[str, Callable[..., Policy]] = {
    "pd": PDPolicy,
    "stand": StandPolicy,
    "lqr": LQRPolicy,
    "random": RandomPolicy,
    "reference": _reference,
    "zero": ZeroPolicy,
    **{name: functools.partial(SB3ZipPolicy, path) for name, path in TERRAIN_POLICIES.items()},
}


def register_policy(name: str, factory: Callable[[], Policy]) -> None:
    """Make `bbbench eval NAME` score the policy `factory()` returns."""
    if name in BUILTIN_POLICIES:
        raise ValueError(f"a built-in policy is already called {name!r}")
    BUILTIN_POLICIES[name] = factory


def load_policy(
    name_or_path: str | Path,
    backend: str = "numpy",
    vecnormalize: str | Path | None = None,
    action_mode: str | None = None,
) -> Policy:
    """A built-in policy by name, or a stable-baselines3 `.zip` by path.

    `vecnormalize`: the `VecNormalize.save` statistics a zip was trained with. A
    zip trained inside VecNormalize needs them: given here, or found where
    rl-zoo3 saves them beside the zip (`policy.normalization_source` says so);
    else `PolicyError`. `action_mode`: the built-ins pd, zero and random act in
    either mode (default discrete); a zip's is its own.
    """
    text = str(name_or_path)
    if text in BUILTIN_POLICIES:
        if vecnormalize is not None:
            raise PolicyError(f"--vecnormalize is for a policy file, not the built-in {text!r}")
        policy = BUILTIN_POLICIES[text]()
        if action_mode is not None and action_mode != policy.action_mode:
            try:
                policy = BUILTIN_POLICIES[text](action_mode=action_mode)
            except TypeError:
                raise PolicyError(
                    f"the built-in policy {text!r} acts in {policy.action_mode} mode only"
                ) from None
        return policy
    path = Path(text)
    if path.suffix.lower() == ".zip" or path.exists():
        policy = SB3ZipPolicy(path, backend=backend)
        if action_mode is not None and action_mode != policy.action_mode:
            raise PolicyError(
                f"{path}: its action space {describe_space(policy.loaded.action_space)} is "
                f"{policy.action_mode}, not {action_mode}"
            )
        _attach_normalization(policy, path, vecnormalize)
        return policy
    raise PolicyError(
        f"unknown policy {text!r}: give a stable-baselines3 .zip file or a built-in policy, "
        f"one of {', '.join(sorted(BUILTIN_POLICIES))}"
    )


def _attach_normalization(policy: SB3ZipPolicy, path: Path, statistics: str | Path | None):
    from bbbench.policies.vecnormalize import find_rl_zoo_statistics, read_statistics

    trained_in_vecnormalize = policy.loaded.vecnormalize  # True, False or None: cannot tell
    if statistics is None and trained_in_vecnormalize is not False:
        statistics = find_rl_zoo_statistics(path)
        if statistics is None and trained_in_vecnormalize:
            raise PolicyError(
                f"{path}: trained inside VecNormalize (observation normalization), and scored "
                f"on raw observations it would score wrong: pass its statistics with "
                f"--vecnormalize PATH (the file VecNormalize.save wrote; rl-zoo3 writes "
                f"<run folder>/<env>/vecnormalize.pkl)"
            )
        if statistics is not None:
            policy.normalization_source = (
                f"observations normalized with {statistics} (found beside the policy, where "
                f"rl-zoo3 saves them)"
            )
    if statistics is not None:
        policy.normalization = read_statistics(statistics, policy.loaded.observation_shape)


def fitting_tasks(policy: Policy) -> list[str]:
    """The latest version of each task of the suite that the policy can play."""
    return [task_id for task_id in list_tasks(latest=True) if policy.mismatch(task_id) is None]
