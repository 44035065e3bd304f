"""The algorithms bbbench evaluates and trains: one record each.

A record says everything the rest of the package asks of an algorithm: its
stable-baselines3 (or sb3-contrib) class, the MLP policy classes its zips name,
the action modes it learns in, its policy's default architecture, whether it
learns on-policy, and its *family* — how its acting network is laid out, which
says how the numpy actor is extracted (`bbbench.policies.sb3.extract`) and how its
parameters are counted before anything is built (`declared_parameters`).

The zip reader (`bbbench.policies.sb3.reader`), the rebuild (`bbbench.policies.sb3.rebuild`),
the recipes and `bbbench train` all read `SB3_ALGORITHMS`: the stable-baselines3 classes a
zip may name (what `bbbench train` trains is `bbbench.training.ALGORITHMS`, built from it
and BenchMARL's). Adding an algorithm is one record here plus its test (and a recipe file
in `bbbench/training/recipes/` to train it with `bbbench train`).
"""

from __future__ import annotations

import dataclasses
import difflib
import importlib
import itertools
import math
from collections.abc import Callable
from typing import Any

from gymnasium import spaces

from bbbench.policies.sb3 import extract
from bbbench.portable import total

NetArch = list[int] | dict[str, list[int]] | None


@dataclasses.dataclass(frozen=True)
class Family:
    """How the acting network of a group of algorithms is laid out."""

    name: str
    # (torch policy, its facts) -> the keywords of MlpActor besides activation and bounds
    extract: Callable[..., dict[str, Any]]
    # (observations, actions, discrete, pi, vf, qf, kwargs, use_sde) -> parameters
    count: Callable[..., int]
    trains_an_optimizer: bool = True  # its policy class takes lr_schedule and optimizer_class


def _mlp_parameters(inputs: int, layers: list[int], outputs: int) -> int:
    """Weights and biases of Linear layers inputs -> layers... -> outputs (0: no head)."""
    widths = [inputs, *layers, *([outputs] if outputs else [])]
    return total(a * b + b for a, b in itertools.pairwise(widths))


def _actor_critic_parameters(observations, actions, discrete, pi, vf, qf, kwargs, use_sde):
    latent_pi, latent_vf = (pi or [observations])[-1], (vf or [observations])[-1]
    log_std = 0 if discrete else latent_pi * actions if use_sde else actions
    return (
        _mlp_parameters(observations, pi, 0)
        + _mlp_parameters(observations, vf, 0)
        + _mlp_parameters(latent_pi, [], actions)
        + _mlp_parameters(latent_vf, [], 1)
        + log_std
    )


def _q_parameters(observations, actions, discrete, pi, vf, qf, kwargs, use_sde):
    outputs = actions * kwargs.get("n_quantiles", 1)
    return 2 * _mlp_parameters(observations, pi, outputs)  # the network and its target


def _sac_parameters(observations, actions, discrete, pi, vf, qf, kwargs, use_sde):
    latent = (pi or [observations])[-1]
    actor = _mlp_parameters(observations, pi, 0) + 2 * _mlp_parameters(latent, [], actions)
    critic = kwargs["n_critics"] * _mlp_parameters(
        observations + actions, qf, kwargs.get("n_quantiles", 1)
    )
    return actor + 2 * critic  # the critics and their targets


def _td3_parameters(observations, actions, discrete, pi, vf, qf, kwargs, use_sde):
    actor = _mlp_parameters(observations, pi, actions)
    critic = kwargs["n_critics"] * _mlp_parameters(observations + actions, qf, 1)
    return 2 * (actor + critic)  # each with its target


def _ars_parameters(observations, actions, discrete, pi, vf, qf, kwargs, use_sde):
    return _mlp_parameters(observations, pi, actions)


ACTOR_CRITIC = Family("actor_critic", extract.actor_critic, _actor_critic_parameters)
Q = Family("q", extract.q_network, _q_parameters)
SAC = Family("sac", extract.sac, _sac_parameters)
TD3 = Family("td3", extract.td3, _td3_parameters)
ARS = Family("ars", extract.ars, _ars_parameters, trains_an_optimizer=False)


@dataclasses.dataclass(frozen=True)
class Algorithm:
    """One supported algorithm's MLP policy, as bbbench reads, rebuilds and trains it."""

    name: str  # as its library and the results JSON name it: "PPO", "QR-DQN"
    model: str  # its class, "module:Name"
    policies: tuple[str, ...]  # its MLP policy classes, "module:Name", as `policy_class` names them
    family: Family
    action_modes: tuple[str, ...]  # the modes it learns in; the first is its default
    activation: str  # its policy's default activation_fn
    net_arch: tuple[int, ...]  # its policy's default net_arch
    on_policy: bool
    # A `data` key only this algorithm writes among those that share its policy class;
    # None for the one that writes none of theirs.
    marker: str | None = None
    policy_defaults: tuple[tuple[str, int], ...] = ()  # policy kwargs its class defaults

    @property
    def key(self) -> str:
        """Its name in rl-zoo3 and on bbbench's command line: "ppo", "qrdqn"."""
        return self.name.lower().replace("-", "")

    @property
    def epsilon_greedy(self) -> bool:
        """Acts epsilon-greedily when asked for stochastic actions (DQN, QR-DQN)."""
        return self.family is Q

    def model_class(self) -> type:
        """Its stable-baselines3 / sb3-contrib class (imported now)."""
        return load_class(self.model)


def load_class(path: str) -> type:
    """The class at "module:Name", one of the table's own paths."""
    module, name = path.split(":")
    return getattr(importlib.import_module(module), name)


_AC_POLICY = "stable_baselines3.common.policies:ActorCriticPolicy"
SB3_ALGORITHMS = {
    algorithm.name: algorithm
    for algorithm in (
        Algorithm(
            "PPO", "stable_baselines3:PPO", (_AC_POLICY,), ACTOR_CRITIC,
            ("discrete", "continuous"), "Tanh", (64, 64), on_policy=True, marker="n_epochs",
        ),
        Algorithm(
            "A2C", "stable_baselines3:A2C", (_AC_POLICY,), ACTOR_CRITIC,
            ("discrete", "continuous"), "Tanh", (64, 64), on_policy=True,
        ),
        Algorithm(
            "DQN", "stable_baselines3:DQN", ("stable_baselines3.dqn.policies:DQNPolicy",), Q,
            ("discrete",), "ReLU", (64, 64), on_policy=False,
        ),
        Algorithm(
            "SAC", "stable_baselines3:SAC", ("stable_baselines3.sac.policies:SACPolicy",), SAC,
            ("continuous",), "ReLU", (256, 256), on_policy=False,
            policy_defaults=(("n_critics", 2),),
        ),
        Algorithm(
            "TD3", "stable_baselines3:TD3", ("stable_baselines3.td3.policies:TD3Policy",), TD3,
            ("continuous",), "ReLU", (400, 300), on_policy=False,
            policy_defaults=(("n_critics", 2),),
        ),
        Algorithm(
            "QR-DQN", "sb3_contrib:QRDQN", ("sb3_contrib.qrdqn.policies:QRDQNPolicy",), Q,
            ("discrete",), "ReLU", (64, 64), on_policy=False,
            policy_defaults=(("n_quantiles", 200),),
        ),
        Algorithm(
            "TQC", "sb3_contrib:TQC", ("sb3_contrib.tqc.policies:TQCPolicy",), SAC,
            ("continuous",), "ReLU", (256, 256), on_policy=False,
            policy_defaults=(("n_critics", 2), ("n_quantiles", 25)),
        ),
        Algorithm(
            "TRPO", "sb3_contrib:TRPO", (_AC_POLICY,), ACTOR_CRITIC,
            ("discrete", "continuous"), "Tanh", (64, 64), on_policy=True, marker="cg_max_steps",
        ),
        Algorithm(
            "ARS", "sb3_contrib:ARS",
            ("sb3_contrib.ars.policies:ARSPolicy", "sb3_contrib.ars.policies:ARSLinearPolicy"),
            ARS, ("discrete", "continuous"), "ReLU", (64, 64), on_policy=False,
        ),
    )
}  # fmt: skip
LINEAR_POLICY = "sb3_contrib.ars.policies:ARSLinearPolicy"  # a policy without hidden layers


def by_key(key: str) -> Algorithm:
    """The algorithm called `key` on the command line ("ppo", "qrdqn"); `ValueError`
    naming the known ones."""
    keys = {algorithm.key: algorithm for algorithm in SB3_ALGORITHMS.values()}
    if key in keys:
        return keys[key]
    raise ValueError(unknown("algorithm", key, tuple(keys)))


def unknown(what: str, given: str, known: tuple[str, ...]) -> str:
    """'unknown algorithm 'ppp'. Did you mean 'ppo'? Known: ...'."""
    close = difflib.get_close_matches(str(given).lower(), known, n=1)
    hint = f" Did you mean {close[0]!r}?" if close else ""
    return f"unknown {what} {given!r}.{hint} Known: {', '.join(known)}"


def algorithm_of(policy_class: str, data: dict[str, Any]) -> Algorithm | None:
    """The algorithm of a zip whose `policy_class` is "module:Name", told apart by the
    `data` keys only it writes where several share the class; None if unsupported."""
    candidates = [a for a in SB3_ALGORITHMS.values() if policy_class in a.policies]
    marked = [a for a in candidates if a.marker is not None and a.marker in data]
    unmarked = [a for a in candidates if a.marker is None]
    return (marked or unmarked or [None])[0]


def action_mode(action_space: spaces.Space) -> str:
    return "discrete" if isinstance(action_space, spaces.Discrete) else "continuous"


def declared_parameters(
    algorithm: Algorithm,
    observation_shape: tuple[int, ...],
    action_space: spaces.Space,
    net_arch: NetArch,
    kwargs: dict[str, Any],
    use_sde: bool = False,
) -> int:
    """The parameters of the network stable-baselines3 would build for this algorithm and
    architecture (critics and target networks included), counted without building it."""
    default = list(algorithm.net_arch)
    if net_arch is None:
        net_arch = default
    pi = net_arch.get("pi", default) if isinstance(net_arch, dict) else net_arch
    vf = net_arch.get("vf", default) if isinstance(net_arch, dict) else net_arch
    qf = net_arch.get("qf", default) if isinstance(net_arch, dict) else net_arch
    discrete = isinstance(action_space, spaces.Discrete)
    actions = int(action_space.n) if discrete else math.prod(action_space.shape)
    kwargs = {**dict(algorithm.policy_defaults), **kwargs}
    return algorithm.family.count(
        math.prod(observation_shape), actions, discrete, pi, vf, qf, kwargs, use_sde
    )
