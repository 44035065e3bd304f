"""Read a stable-baselines3 `.zip` without trusting it.

stable-baselines3's own `load` unpickles the `:serialized:` values of the zip's
`data` member, so a crafted file runs code during `PPO.load`. This module never
calls it (nor `BasePolicy.load`, nor `pickle`) on a submitted file:

1. The zip's member names are allowlisted and each member's size is capped
   before it is inflated; inflating stops at the cap and at the size the
   member's header declares (`bbbench.policies.archive`).
2. `data` is read as plain JSON. `policy_class` must be, byte for byte, a
   plain reference to a class (the pickle stable-baselines3 writes for one),
   and bbbench reads its module and name without unpickling; an MLP policy of
   a supported algorithm is evaluated, any other class is "not supported".
   Only the keys where stable-baselines3 itself pickles (spaces, schedules,
   buffers...) may hold `:serialized:` values, and those values are never
   decoded: bbbench reads the plain fields SB3 writes beside them. Any other
   key, or pickled content where plain data is expected, refuses the file.
3. The parameters of the network the zip declares are counted from its plain
   architecture, and refused above `MAX_PARAMETERS`, before anything is built.
4. `policy.pth` is read with `torch.load(weights_only=True)`, every tensor's
   shape and dtype checked before its values are copied
   (`bbbench.policies.sb3.weights`).
5. The network is rebuilt from the task's own spaces and an allowlisted
   architecture, and the weights are loaded with `strict=True`
   (`bbbench.policies.sb3.rebuild`); the acting layers are copied out to numpy
   (`bbbench.policies.sb3.extract`).

The supported algorithms, their policy classes and how each is laid out are one table,
`bbbench.policies.sb3.algorithms`.

Supported: the MLP policies of stable-baselines3's PPO, A2C, DQN, SAC and TD3
and of sb3-contrib's QR-DQN, TQC, TRPO and ARS (MLP or linear), on Box
observations; gSDE (`use_sde=True`) when acting deterministically. A policy
trained inside `VecNormalize` is detected (stable-baselines3 saves its last
unnormalized observation only then) and needs its statistics
(`bbbench.policies.sb3.vecnormalize`).
"""

from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from bbbench.policies.archive import Archive, read_file
from bbbench.policies.errors import PolicyError, RefusedForSafety
from bbbench.policies.file_policy import MAX_PARAMETERS
from bbbench.policies.sb3.algorithms import (
    LINEAR_POLICY,
    Algorithm,
    NetArch,
    Q,
    action_mode,
    declared_parameters,
)
from bbbench.policies.sb3.data import (
    MAX_QUANTILES,
    algorithm_and_class,
    check_keys,
    integer,
    observation_shape,
    parse_data,
    policy_kwargs,
    read_action_space,
)
from bbbench.policies.sb3.weights import read_weights

MAX_FILE_BYTES = 256 * 2**20
# Every member a stable-baselines3 zip may hold, with the most bbbench lets it inflate to.
MEMBER_LIMITS = {
    "data": 2**20,
    "policy.pth": 64 * 2**20,
    "pytorch_variables.pth": 2**20,
    "policy.optimizer.pth": 128 * 2**20,
    "actor.optimizer.pth": 128 * 2**20,
    "critic.optimizer.pth": 128 * 2**20,
    "ent_coef_optimizer.pth": 2**20,
    "_stable_baselines3_version": 64,
    "system_info.txt": 64 * 2**10,
}


@dataclasses.dataclass(frozen=True, eq=False)
class SB3Zip:
    """What a stable-baselines3 zip holds, read safely: plain facts and numpy weights."""

    name: str
    sha256: str
    algorithm: Algorithm
    policy_class: str  # "module:Name", one of the algorithm's allowlisted classes
    observation_shape: tuple[int, ...]
    action_space: spaces.Discrete | spaces.Box
    net_arch: NetArch  # None: the algorithm's default
    activation: str | None  # None: the algorithm's default
    architecture: dict[str, Any]  # the other policy kwargs, passed to the class as given
    exploration_rate: float  # DQN's and QR-DQN's epsilon when acting stochastically
    weights: dict[str, np.ndarray]  # policy.pth, as float32 numpy arrays
    use_sde: bool = False  # trained with gSDE
    # Trained inside VecNormalize? True, False, or None where the zip cannot tell
    # (see `trained_in_vecnormalize`).
    vecnormalize: bool | None = False

    @property
    def action_mode(self) -> str:
        return action_mode(self.action_space)


# -- reading the zip ------------------------------------------------------------


def read_sb3_zip(path: str | Path) -> SB3Zip:
    """Read a stable-baselines3 zip safely; `PolicyError` (or `RefusedForSafety`) if not."""
    path = Path(path)
    content = read_file(path, MAX_FILE_BYTES, "a stable-baselines3 .zip")
    sha256 = hashlib.sha256(content).hexdigest()
    archive = Archive(path, content, MEMBER_LIMITS, required=("data", "policy.pth"))
    data = parse_data(path, archive.read("data"))
    algorithm, policy_class = algorithm_and_class(path, data)
    check_keys(path, data)
    shape = observation_shape(path, data["observation_space"])
    action_space = read_action_space(path, data["action_space"])
    kwargs = policy_kwargs(path, data.get("policy_kwargs", {}))
    if action_mode(action_space) not in algorithm.action_modes:
        raise PolicyError(f"{path}: a {algorithm.name} policy with a {action_space} action space")
    use_sde = data.get("use_sde", False)
    if not isinstance(use_sde, bool):
        raise PolicyError(f"{path}: use_sde must be true or false, got {use_sde!r}")
    use_sde = use_sde or bool(kwargs.get("use_sde"))
    quantiles = dict(algorithm.policy_defaults).get("n_quantiles")
    if algorithm.family is Q and quantiles and "n_quantiles" not in kwargs:
        # QR-DQN may keep it beside its policy kwargs
        kwargs["n_quantiles"] = integer(path, data, "n_quantiles", quantiles, MAX_QUANTILES)
    linear = policy_class == LINEAR_POLICY
    if linear and ("net_arch" in kwargs or "activation" in kwargs):
        raise PolicyError(f"{path}: ARS's LinearPolicy takes no net_arch or activation_fn")
    exploration_rate = 0.0
    if algorithm.epsilon_greedy:
        exploration_rate = data.get("exploration_rate", 0.0)
        if not isinstance(exploration_rate, int | float) or not 0.0 <= exploration_rate <= 1.0:
            raise PolicyError(f"{path}: exploration_rate must be a number in [0, 1]")
    declared = declared_parameters(
        algorithm,
        shape,
        action_space,
        [] if linear else kwargs.get("net_arch"),
        kwargs,
        use_sde,
    )
    if declared > MAX_PARAMETERS:
        raise RefusedForSafety(
            f"{path}: its {algorithm.name} network (net_arch "
            f"{kwargs.get('net_arch', 'default')}) has {declared:,} parameters, more than "
            f"the {MAX_PARAMETERS:,} bbbench evaluates"
        )
    weights = read_weights(path, archive.read("policy.pth"))
    return SB3Zip(
        name=path.name,
        sha256=sha256,
        algorithm=algorithm,
        policy_class=policy_class,
        observation_shape=shape,
        action_space=action_space,
        net_arch=kwargs.pop("net_arch", None),
        activation=kwargs.pop("activation", None),
        architecture=kwargs,
        exploration_rate=float(exploration_rate),
        weights=weights,
        use_sde=use_sde,
        vecnormalize=trained_in_vecnormalize(algorithm, data),
    )


def trained_in_vecnormalize(algorithm: Algorithm, data: dict[str, Any]) -> bool | None:
    """Whether the zip's plain data shows training inside VecNormalize.

    stable-baselines3 keeps `_last_original_obs` (the last observation before
    normalization) only under VecNormalize on on-policy algorithms (PPO, A2C,
    TRPO): there a value means VecNormalize, null means none. Off-policy
    algorithms (DQN, SAC, TD3, QR-DQN, TQC) also keep it without VecNormalize (the
    observation before the last step): a value there cannot tell (None).
    """
    if data.get("_last_original_obs") is None:
        return False
    return True if algorithm.on_policy else None
