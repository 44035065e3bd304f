"""The stable-baselines3 route's recipes: rl-zoo3 hyperparameter files shipped in the
package, one per algorithm, keyed by task ID (`bbbench/training/recipes/ppo.yml`).

The same file drives `bbbench train` and rl-zoo3's own `python -m rl_zoo3.train --algo
ppo --env bbbench/Bumps-v1 --gym-packages bbbench -conf <file>`. The keys rl-zoo3
reads besides the algorithm's own arguments are understood here too: `n_envs`,
`n_timesteps`, `policy`, `policy_kwargs` (a `dict(...)` string, read without `eval`),
`noise_type` and `noise_std` (TD3's action noise), `normalize` (train inside
stable-baselines3's `VecNormalize`: `true`, or a dict string of its keywords such as
"{'norm_obs': True, 'norm_reward': False}"; its `gamma` is the recipe's, as in rl-zoo3).
rl-zoo3's `env_wrapper` is refused:
a shipped recipe learns from the task's own reward, and if a task cannot be learned from
it, the task is wrong.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bbbench.policies.sb3.algorithms import by_key, unknown
from bbbench.policies.sb3.vecnormalize import STATISTICS_FILE
from bbbench.tasks.suite import SUITE, latest_version, spec
from bbbench.training.algorithms import SB3, trainable
from bbbench.training.recipe_files import read_recipe_file

MIX = "single-bot mix"  # the recipe key of a generalist trained on several tasks
_ZOO_KEYS = (
    "n_envs",
    "n_timesteps",
    "policy",
    "policy_kwargs",
    "noise_type",
    "noise_std",
    "normalize",
)
# The VecNormalize keywords a recipe's `normalize` may set (gamma is the recipe's own).
_NORMALIZE_KEYS = ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "epsilon")
_ACTIVATIONS = ("Tanh", "ReLU", "LeakyReLU", "ELU", "SiLU", "Sigmoid")


@dataclasses.dataclass(frozen=True)
class Recipe:
    """How to train `algorithm` on `key` (a task ID, or `MIX`)."""

    algorithm: str
    key: str
    n_envs: int
    n_timesteps: int
    policy: str
    hyperparameters: dict[str, Any]  # keyword arguments of the algorithm's class
    policy_kwargs: dict[str, Any]
    noise_std: float | None = None  # Gaussian action noise (TD3)
    # Keywords of the VecNormalize the policy trains inside; None: raw observations.
    normalize: dict[str, Any] | None = None

    def batch(self, slots: int) -> int:
        """Steps of one rollout over a VecEnv of `slots` envs (a multi-bot world counts
        one per bot): the least a training collects before it learns (an on-policy
        algorithm's `n_steps` per slot, else one step per slot)."""
        steps = self.hyperparameters.get("n_steps")
        if steps is None:  # the algorithm's own default
            parameters = inspect.signature(by_key(self.algorithm).model_class()).parameters
            steps = parameters["n_steps"].default if "n_steps" in parameters else 1
        return int(steps) * slots

    def batch_of(self, tasks: Sequence[str], n_envs: int, workers: int | None) -> int:
        """Steps a rollout of `n_envs` envs of `tasks` collects
        (`bbbench.training.checks.check_collection`)."""
        if workers is not None:
            raise ValueError(
                f"--workers sets the processes of IPPO's and MAPPO's batched worlds; "
                f"{self.algorithm} collects with --n-envs"
            )
        return self.batch(vec_slots(tasks, n_envs))

    def record(self) -> dict[str, Any]:
        """As `train.json` records it."""
        return {
            "algorithm": self.algorithm,
            "recipe": self.key,
            "n_envs": self.n_envs,
            "n_timesteps": self.n_timesteps,
            "policy": self.policy,
            "hyperparameters": self.hyperparameters,
            "policy_kwargs": _show_policy_kwargs(self.policy_kwargs),
            **({"noise_std": self.noise_std} if self.noise_std is not None else {}),
            **({"normalize": self.normalize} if self.normalize is not None else {}),
        }


def recipes(algorithm: str, file: str | Path | None = None) -> dict[str, dict[str, Any]]:
    """The recipe table of `algorithm`: its shipped file, or `file` (the same format)."""
    if trainable(algorithm).route != SB3:
        raise ValueError(f"{algorithm} trains with BenchMARL, from a recipe of its own")
    return read_recipe_file(algorithm, file)


def recipe(algorithm: str, key: str, file: str | Path | None = None) -> Recipe:
    """`algorithm`'s recipe for `key` (from `file`, else the shipped one); `ValueError`
    naming the ones there are."""
    table = recipes(algorithm, file)
    if key not in table:
        newer = _newer_version(key)
        if newer is not None:
            raise ValueError(
                f"no {algorithm} recipe for {key}: the recipes train the latest version of "
                f"each task, here {newer} (the reward in which staying up never costs)"
            )
        raise ValueError(
            f"no {algorithm} recipe for {key}; {algorithm}.yml has recipes for {', '.join(table)}"
        )
    entry = dict(table[key])
    if "env_wrapper" in entry:
        raise ValueError(
            f"{algorithm}.yml, {key}: env_wrapper is refused: a recipe learns from the task's "
            f"own reward (normalizing observations or rewards in the algorithm is fine)"
        )
    _check_keys(algorithm, f"{Path(file).name if file else f'{algorithm}.yml'}, {key}", entry)
    noise_type = entry.get("noise_type")
    if noise_type not in (None, "normal"):
        raise ValueError(f"{algorithm}.yml, {key}: noise_type {noise_type!r}: only 'normal'")
    return Recipe(
        algorithm=algorithm,
        key=key,
        n_envs=int(entry.get("n_envs", 1)),
        n_timesteps=int(entry["n_timesteps"]),
        policy=entry.get("policy", "MlpPolicy"),
        hyperparameters={k: v for k, v in entry.items() if k not in _ZOO_KEYS},
        policy_kwargs=parse_policy_kwargs(entry.get("policy_kwargs", "dict()")),
        noise_std=float(entry["noise_std"]) if noise_type else None,
        normalize=parse_normalize(entry.get("normalize", False), f"{algorithm}.yml, {key}"),
    )


# What bbbench passes the algorithm's class itself: a recipe cannot set them.
_SET_BY_BBBENCH = ("env", "seed", "device", "verbose", "action_noise", "_init_setup_model")


def _check_keys(algorithm: str, where: str, entry: dict[str, Any]) -> None:
    """`ValueError` naming a key of the recipe that neither rl-zoo3's format nor the
    algorithm's class takes (a misspelt `learning_rte`), with the keys there are."""
    parameters = inspect.signature(by_key(algorithm).model_class()).parameters
    known = tuple(sorted({*_ZOO_KEYS, *parameters} - set(_SET_BY_BBBENCH)))
    for name in entry:
        if name not in known:
            raise ValueError(f"{where}: {unknown('key', name, known)}")


def parse_normalize(value: Any, where: str) -> dict[str, Any] | None:
    """rl-zoo3's `normalize`: false (none), true (VecNormalize's defaults) or a dict string
    of VecNormalize keywords, read as data; the keywords VecNormalize takes, or None."""
    if value is False or value is None:
        return None
    if value is True:
        return {}
    try:
        keywords = ast.literal_eval(value) if isinstance(value, str) else value
    except (ValueError, SyntaxError):
        keywords = None
    if not isinstance(keywords, dict):
        raise ValueError(
            f"{where}: normalize {value!r}: expected true, false or a dict of VecNormalize "
            f"keywords such as \"{{'norm_obs': True, 'norm_reward': False}}\""
        )
    unknown = sorted(set(keywords) - set(_NORMALIZE_KEYS))
    if unknown:
        raise ValueError(
            f"{where}: normalize sets {', '.join(map(str, unknown))}; it takes "
            f"{', '.join(_NORMALIZE_KEYS)} (gamma is the recipe's)"
        )
    return dict(keywords)


def _newer_version(key: str) -> str | None:
    """The latest version of `key`'s task, if `key` is an older version of it."""
    if key not in SUITE or latest_version(key) == key:
        return None
    return latest_version(key)


def parse_policy_kwargs(text: str) -> dict[str, Any]:
    """rl-zoo3's `policy_kwargs` string, 'dict(net_arch=[64, 64], activation_fn=nn.ReLU)',
    read as data: literal values, and torch.nn activations by name."""
    import torch.nn  # lazy: torch, for training only

    try:
        call = ast.parse(text, mode="eval").body
    except SyntaxError:
        call = None
    if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Name)) or call.args:
        raise ValueError(f"policy_kwargs {text!r}: expected dict(name=value, ...)")
    if call.func.id != "dict":
        raise ValueError(f"policy_kwargs {text!r}: expected dict(name=value, ...)")
    kwargs = {}
    for keyword in call.keywords:
        value = keyword.value
        if isinstance(value, ast.Attribute) and value.attr in _ACTIVATIONS:
            kwargs[keyword.arg] = getattr(torch.nn, value.attr)
        else:
            try:
                kwargs[keyword.arg] = ast.literal_eval(value)
            except ValueError:
                raise ValueError(
                    f"policy_kwargs {text!r}: {keyword.arg} must be a literal or an nn "
                    f"activation ({', '.join(_ACTIVATIONS)})"
                ) from None
    return kwargs


def _show_policy_kwargs(kwargs: dict[str, Any]) -> dict[str, Any]:
    return {k: v.__name__ if isinstance(v, type) else v for k, v in kwargs.items()}


def vec_slots(tasks: Sequence[str], n_envs: int) -> int:
    """The slots of the VecEnv `n_envs` envs of `tasks` make (a multi-bot world: one per
    bot)."""
    task = spec(tasks[0])
    return n_envs * (task.group.n_bots if task.multi_agent else 1)


def statistics_path(out: str | Path, plan: Recipe) -> Path | None:
    """Where the VecNormalize statistics of the policy `out` go if `plan` trains inside
    VecNormalize: rl-zoo3's layout, which `bbbench eval` finds on its own (`policy.zip`
    -> `policy/vecnormalize.pkl`). None for a recipe without; `ValueError` if a file is
    in the way."""
    if plan.normalize is None:
        return None
    out = Path(out)
    statistics = out.parent / out.stem / STATISTICS_FILE
    if statistics.parent.exists() and not statistics.parent.is_dir():
        raise ValueError(
            f"--out {out}: its recipe trains inside VecNormalize, whose statistics go to "
            f"{statistics}, but {statistics.parent} is a file: choose another --out"
        )
    return statistics
