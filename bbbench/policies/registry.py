"""The built-in policies by name, and `load_policy`: a name or a file to a `Policy`."""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bbbench.policies.controllers.builtin import (
    CrossingPolicy,
    LeggedPolicy,
    LQRPolicy,
    MixedTeamPolicy,
    PDPolicy,
    PerBotPolicy,
    RandomPolicy,
    RendezvousPolicy,
    StandPolicy,
    SteerAvoidPolicy,
    SteerPolicy,
    TeamPolicy,
    ZeroPolicy,
)
from bbbench.policies.errors import PolicyError
from bbbench.policies.onnx.policy import OnnxPolicy
from bbbench.policies.onnx.team import TeamFilePolicy, is_team_file
from bbbench.policies.policy import Policy, describe_space
from bbbench.policies.sb3.policy import SB3ZipPolicy
from bbbench.policies.sb3.vecnormalize import find_rl_zoo_statistics, read_statistics
from bbbench.tasks.suite import spec


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
    "legged": LeggedPolicy,
    "team": TeamPolicy,
    "mixed-team": MixedTeamPolicy,
    "per-bot": PerBotPolicy,
    "crossing": CrossingPolicy,
    "steer": SteerPolicy,
    "steer-avoid": SteerAvoidPolicy,
    "rendezvous": RendezvousPolicy,
    "random": RandomPolicy,
    "reference": _reference,
    "zero": ZeroPolicy,
    **{name: functools.partial(SB3ZipPolicy, path) for name, path in TERRAIN_POLICIES.items()},
}


def classical_controller(task_id: str) -> str:
    """The built-in controller of a task: the one its learned baselines are set against
    (docs/baselines.md) and whose play a MARL recipe's observation statistics are measured
    on. Its scenario's (`Scenario.controller`: `team` on the team tasks, `steer-avoid` on
    Swap), else its robot's (`Robot.controller`: PD, `legged`, `steer`). Raises ValueError
    for an unknown task."""
    task = spec(task_id)
    return task.scenario_class.controller or task.robot_model.controller


def register_policy(name: str, factory: Callable[[], Policy]) -> None:
    """Make `bbbench eval NAME` score the policy `factory()` returns."""
    if name in BUILTIN_POLICIES:
        raise ValueError(f"a built-in policy is already called {name!r}")
    BUILTIN_POLICIES[name] = factory


@dataclasses.dataclass(frozen=True)
class Loader:
    """How `load_policy` reads one kind of policy: what it is, how it is recognized (by
    name, by its file's suffix or first bytes), and how it is loaded."""

    kind: str
    claims: Callable[[str], bool]
    load: Callable[..., Policy]
    options: tuple[str, ...]  # the keywords of `load_policy` that apply to it


def _is_onnx(text: str) -> bool:
    path = Path(text)
    if path.suffix.lower() == ".onnx":
        return True
    return path.suffix.lower() != ".zip" and path.is_file() and _first_bytes(path) != b"PK"


def _is_team(text: str) -> bool:
    return is_team_file(Path(text))


def _is_zip(text: str) -> bool:
    return Path(text).suffix.lower() == ".zip" or Path(text).is_file()


def _first_bytes(path: Path) -> bytes:
    try:
        with open(path, "rb") as file:
            return file.read(2)
    except OSError:
        return b""


def _load_builtin(text: str, action_mode: str | None = None, **_: Any) -> Policy:
    policy = BUILTIN_POLICIES[text]()
    if action_mode is not None and action_mode != policy.action_mode:
        try:
            policy = BUILTIN_POLICIES[text](action_mode=action_mode)
        except TypeError:
            raise PolicyError(
                f"the built-in policy {text!r} acts in {policy.action_mode} mode only"
            ) from None
    return policy


def _load_zip(
    text: str, backend: str = "numpy", vecnormalize=None, action_mode=None, **_: Any
) -> Policy:
    path = Path(text)
    policy = SB3ZipPolicy(path, backend=backend)
    _check_mode(policy, path, action_mode)
    _attach_normalization(policy, path, vecnormalize)
    return policy


def _load_onnx(
    text: str, action_mode=None, observation=None, action_space=None, **_: Any
) -> Policy:
    policy = OnnxPolicy(text, observation=observation, action_space=action_space)
    _check_mode(policy, Path(text), action_mode)
    return policy


def _check_mode(policy: Policy, path: Path, action_mode: str | None) -> None:
    if action_mode is not None and action_mode != policy.action_mode:
        raise PolicyError(
            f"{path}: its action space {describe_space(policy.action_space)} is "
            f"{policy.action_mode}, not {action_mode}"
        )


# What `load_policy` reads, in the order it asks: a new kind of policy file is one row.
LOADERS = (
    Loader(
        "built-in policy", lambda text: text in BUILTIN_POLICIES, _load_builtin, ("action_mode",)
    ),
    Loader("ONNX model", _is_onnx, _load_onnx, ("action_mode", "observation", "action_space")),
    Loader("mixed team's policy file", _is_team, lambda text, **_: TeamFilePolicy(text), ()),
    Loader("stable-baselines3 zip", _is_zip, _load_zip, ("action_mode", "backend", "vecnormalize")),
)
_FLAGS = {
    "vecnormalize": "--vecnormalize",
    "observation": "--observation",
    "action_space": "--action-space",
}


def load_policy(
    name_or_path: str | Path,
    backend: str = "numpy",
    vecnormalize: str | Path | None = None,
    action_mode: str | None = None,
    observation: int | None = None,
    action_space: str | None = None,
) -> Policy:
    """A built-in policy by name, a stable-baselines3 `.zip` or an ONNX model by path
    (`LOADERS`).

    `vecnormalize`: the `VecNormalize.save` statistics a zip was trained with. A
    zip trained inside VecNormalize needs them: given here, or found where
    rl-zoo3 saves them beside the zip (`policy.normalization_source` says so);
    else `PolicyError`. `action_mode`: the built-ins pd, zero and random act in
    either mode (default discrete); a file's is its own. `observation` and
    `action_space`: the contract of an ONNX file whose metadata carries none
    (`bbbench.policies.onnx.contract`).
    """
    text = str(name_or_path)
    given = {
        "backend": backend,
        "vecnormalize": vecnormalize,
        "action_mode": action_mode,
        "observation": observation,
        "action_space": action_space,
    }
    for loader in LOADERS:
        if loader.claims(text):
            for option, flag in _FLAGS.items():
                if given[option] is not None and option not in loader.options:
                    raise PolicyError(f"{flag} does not apply to {text!r}, a {loader.kind}")
            return loader.load(text, **given)
    raise PolicyError(
        f"unknown policy {text!r}: give a stable-baselines3 .zip, an ONNX model (.onnx) or a "
        f"built-in policy, one of {', '.join(sorted(BUILTIN_POLICIES))}"
    )


def _attach_normalization(policy: SB3ZipPolicy, path: Path, statistics: str | Path | None):
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
