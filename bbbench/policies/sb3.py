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
   (`bbbench.policies.weights`).
5. The network is rebuilt from the task's own spaces and an allowlisted
   architecture, and the weights are loaded with `strict=True`.

Supported: the MLP policies of stable-baselines3's PPO, A2C, DQN, SAC and TD3
and of sb3-contrib's QR-DQN, TQC, TRPO and ARS (MLP or linear), on Box
observations; gSDE (`use_sde=True`) when acting deterministically. A policy
trained inside `VecNormalize` is detected (stable-baselines3 saves its last
unnormalized observation only then) and needs its statistics
(`bbbench.policies.vecnormalize`).
"""

from __future__ import annotations

import base64
import binascii
import dataclasses
import hashlib
import itertools
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from bbbench.policies.archive import Archive, read_file
from bbbench.policies.errors import PolicyError, RefusedForSafety
from bbbench.policies.mlp import ACTIVATIONS, MlpActor
from bbbench.policies.weights import MAX_PARAMETERS, read_weights

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
_MAX_JSON_DEPTH = 32  # data nests a few levels; deeper is not a model.save() file

# The attributes stable-baselines3 2.x and sb3-contrib save in `data`.
_PICKLED_BY_SB3 = frozenset(
    {
        # values SB3 cloudpickles when they are not plain JSON; bbbench never decodes them
        "policy_class",
        "policy_kwargs",
        "observation_space",
        "action_space",
        "lr_schedule",
        "learning_rate",
        "clip_range",
        "clip_range_vf",
        "exploration_schedule",
        "rollout_buffer_class",
        "rollout_buffer_kwargs",
        "replay_buffer_class",
        "replay_buffer_kwargs",
        "train_freq",
        "action_noise",
        "ent_coef",
        "target_kl",
        "_last_obs",
        "_last_episode_starts",
        "_last_original_obs",
        "ep_info_buffer",
        "ep_success_buffer",
        "weights",  # ARS: its flat parameter vector (a tensor)
        "delta_std_schedule",  # ARS
        "target_entropy",  # a numpy float in TQC
    }
)
_PLAIN = frozenset(
    {
        "_current_progress_remaining",
        "_episode_num",
        "_n_calls",
        "_n_updates",
        "_num_timesteps_at_start",
        "_stats_window_size",
        "_total_timesteps",
        "actor_batch_norm_stats",
        "actor_batch_norm_stats_target",
        "batch_norm_stats",
        "batch_norm_stats_target",
        "batch_size",
        "buffer_size",
        "critic_batch_norm_stats",
        "critic_batch_norm_stats_target",
        "exploration_final_eps",
        "exploration_fraction",
        "exploration_initial_eps",
        "exploration_rate",
        "gae_lambda",
        "gamma",
        "gradient_steps",
        "learning_starts",
        "max_grad_norm",
        "n_envs",
        "n_epochs",
        "n_steps",
        "normalize_advantage",
        "num_timesteps",
        "optimize_memory_usage",
        "policy_delay",
        "sde_sample_freq",
        "seed",
        "start_time",
        "target_noise_clip",
        "target_policy_noise",
        "target_update_interval",
        "tau",
        "tensorboard_log",
        "use_sde",
        "use_sde_at_warmup",
        "verbose",
        "vf_coef",
        # sb3-contrib: QR-DQN, TQC, TRPO, ARS
        "n_quantiles",
        "top_quantiles_to_drop_per_net",
        "cg_damping",
        "cg_max_steps",
        "line_search_max_iter",
        "line_search_shrinking_factor",
        "n_critic_updates",
        "sub_sampling_factor",
        "alive_bonus_offset",
        "n_delta",
        "n_eval_episodes",
        "n_params",
        "n_top",
        "old_count",
        "pop_size",
        "processes",
        "zero_policy",
    }
)


@dataclasses.dataclass(frozen=True)
class Algorithm:
    """What bbbench knows of one supported algorithm's MLP policy."""

    name: str
    family: str  # how its acting network is laid out: see SB3Policy.actor
    activation: str  # its policy's default activation_fn
    net_arch: tuple[int, ...]  # its policy's default net_arch


ALGORITHMS = {
    algorithm.name: algorithm
    for algorithm in (
        Algorithm("PPO", "actor_critic", "Tanh", (64, 64)),
        Algorithm("A2C", "actor_critic", "Tanh", (64, 64)),
        Algorithm("DQN", "q", "ReLU", (64, 64)),
        Algorithm("SAC", "sac", "ReLU", (256, 256)),
        Algorithm("TD3", "td3", "ReLU", (400, 300)),
        Algorithm("QR-DQN", "q", "ReLU", (64, 64)),
        Algorithm("TQC", "sac", "ReLU", (256, 256)),
        Algorithm("TRPO", "actor_critic", "Tanh", (64, 64)),
        Algorithm("ARS", "ars", "ReLU", (64, 64)),
    )
}
# The MLP policy class of each algorithm, as `policy_class` names it.
_POLICY_CLASSES = {
    ("stable_baselines3.common.policies", "ActorCriticPolicy"): ("PPO", "A2C", "TRPO"),
    ("stable_baselines3.dqn.policies", "DQNPolicy"): ("DQN",),
    ("stable_baselines3.sac.policies", "SACPolicy"): ("SAC",),
    ("stable_baselines3.td3.policies", "TD3Policy"): ("TD3",),
    ("sb3_contrib.qrdqn.policies", "QRDQNPolicy"): ("QR-DQN",),
    ("sb3_contrib.tqc.policies", "TQCPolicy"): ("TQC",),
    ("sb3_contrib.ars.policies", "ARSPolicy"): ("ARS",),
    ("sb3_contrib.ars.policies", "ARSLinearPolicy"): ("ARS",),
}
# What to call a policy class bbbench knows but does not evaluate.
_UNSUPPORTED = (
    ("Recurrent", "RecurrentPPO (a recurrent policy)"),
    ("Maskable", "MaskablePPO (a maskable policy)"),
    ("CrossQ", "CrossQ"),
    ("Cnn", "a CNN policy"),
    ("MultiInput", "a MultiInput (dict observation) policy"),
)

# policy_kwargs bbbench understands: the architecture, what it passes to the policy
# class as given, and what only matters for training.
_PASSED_THROUGH_KWARGS = (
    "n_critics",
    "share_features_extractor",
    "n_quantiles",
    "use_sde",
    "squash_output",
    "with_bias",
    "clip_mean",
    "full_std",
    "use_expln",
)
_ARCHITECTURE_KWARGS = ("net_arch", "activation_fn", *_PASSED_THROUGH_KWARGS)
_TRAINING_ONLY_KWARGS = (
    "ortho_init",
    "log_std_init",
    "optimizer_class",
    "optimizer_kwargs",
    "normalize_images",
)
_MAX_LAYERS, _MAX_WIDTH = 8, 4096
_MAX_QUANTILES, _MAX_CRITICS = 1000, 8
_ACTIVATION_REPR = re.compile(r"<class 'torch\.nn\.modules\.activation\.(\w+)'>")
_BOX_TYPE = "<class 'gymnasium.spaces.box.Box'>"
_DISCRETE_TYPE = "<class 'gymnasium.spaces.discrete.Discrete'>"
_DIGITS = re.compile(r"[0-9]{1,9}")


@dataclasses.dataclass(frozen=True, eq=False)
class SB3Policy:
    """A stable-baselines3 MLP policy read safely: plain facts and numpy weights."""

    name: str
    sha256: str
    algorithm: str
    observation_shape: tuple[int, ...]
    action_space: spaces.Discrete | spaces.Box
    net_arch: list[int] | dict[str, list[int]] | None  # None: the algorithm's default
    activation: str | None  # None: the algorithm's default
    architecture: dict[str, Any]  # the other policy kwargs, passed to the class as given
    exploration_rate: float  # DQN's and QR-DQN's epsilon when acting stochastically
    weights: dict[str, np.ndarray]  # policy.pth, as float32 numpy arrays
    sb3_version: str
    use_sde: bool = False  # trained with gSDE
    # Trained inside VecNormalize? True, False, or None where the zip cannot tell
    # (see `trained_in_vecnormalize`).
    vecnormalize: bool | None = False
    linear: bool = False  # ARS's LinearPolicy

    @property
    def action_mode(self) -> str:
        return "discrete" if isinstance(self.action_space, spaces.Discrete) else "continuous"

    @property
    def family(self) -> str:
        return ALGORITHMS[self.algorithm].family

    def torch_policy(self, observation_space: spaces.Box, action_space: spaces.Space):
        """stable-baselines3's own policy module for these spaces, weights loaded strictly."""
        import torch

        kwargs = dict(self.architecture)
        if self.net_arch is not None:
            kwargs["net_arch"] = self.net_arch
        if self.activation is not None:
            kwargs["activation_fn"] = getattr(torch.nn, self.activation)
        if self.family == "ars":
            kwargs.pop("use_sde", None)
        else:
            # An optimizer is for training; building torch's Adam costs over a second.
            kwargs["optimizer_class"] = _NoOptimizer
            kwargs["lr_schedule"] = _no_learning
        if self.family == "actor_critic" and self.use_sde:
            kwargs["use_sde"] = True  # the algorithm, not policy_kwargs, passes it
        try:
            policy = _policy_class(self.algorithm, self.linear)(
                observation_space, action_space, **kwargs
            )
        except (TypeError, ValueError, AssertionError) as error:
            raise PolicyError(
                f"{self.name}: cannot build its {self.algorithm} network: {error}"
            ) from None
        state = {key: torch.from_numpy(value) for key, value in self.weights.items()}
        try:
            policy.load_state_dict(state, strict=True)
        except RuntimeError as error:
            detail = " ".join(str(error).split())
            raise PolicyError(
                f"{self.name}: its weights do not fit a {self.algorithm} MLP with "
                f"net_arch={self.net_arch or 'default'} for {observation_space} -> "
                f"{action_space}: {detail[:300]}"
            ) from None
        policy.set_training_mode(False)
        return policy

    def actor(self, observation_space: spaces.Box, action_space: spaces.Space) -> MlpActor:
        """The acting network in numpy, read from the strictly loaded torch module."""
        policy = self.torch_policy(observation_space, action_space)
        activation = self.activation or ALGORITHMS[self.algorithm].activation
        box = isinstance(action_space, spaces.Box)
        squash = bool(self.architecture.get("squash_output", False))
        log_std, epsilon, quantiles, mean_clip = None, None, 1, None
        if self.family == "actor_critic":
            hidden = _linears(policy.mlp_extractor.policy_net)
            head = _linear(policy.action_net)
            output = "argmax" if not box else "tanh" if squash else "gaussian"
            if box and not self.use_sde:
                log_std = policy.log_std.detach().numpy().copy()
        elif self.family == "q":
            if self.algorithm == "DQN":
                *hidden, head = _linears(policy.q_net.q_net)
            else:  # QR-DQN: the head gives n_quantiles values per action
                *hidden, head = _linears(policy.quantile_net.quantile_net)
                quantiles = policy.n_quantiles
            output, epsilon = "argmax", self.exploration_rate
        elif self.family == "sac":
            hidden = _linears(policy.actor.latent_pi)
            [head] = _linears(policy.actor.mu)
            output = "squashed_gaussian"
            if self.use_sde:
                mean_clip = _hardtanh_bound(policy.actor.mu)
            else:
                log_std = _linear(policy.actor.log_std)
        elif self.family == "td3":  # its last layer is followed by tanh
            *hidden, head = _linears(policy.actor.mu)
            output = "tanh"
        else:  # ARS: tanh-squashed, clipped, or the argmax of its logits
            *hidden, head = _linears(policy.action_net)
            output = "argmax" if not box else "tanh" if policy.squash_output else "clip"
        return MlpActor(
            hidden=tuple(hidden),
            activation=activation,
            head=head,
            output=output,
            log_std=log_std,
            epsilon=epsilon,
            low=action_space.low.copy() if box else None,
            high=action_space.high.copy() if box else None,
            quantiles=quantiles,
            mean_clip=mean_clip,
        )


def _policy_class(algorithm: str, linear: bool = False) -> type:
    if algorithm in ("PPO", "A2C", "TRPO"):
        from stable_baselines3.common.policies import ActorCriticPolicy

        return ActorCriticPolicy
    if algorithm == "DQN":
        from stable_baselines3.dqn.policies import DQNPolicy

        return DQNPolicy
    if algorithm == "SAC":
        from stable_baselines3.sac.policies import SACPolicy

        return SACPolicy
    if algorithm == "TD3":
        from stable_baselines3.td3.policies import TD3Policy

        return TD3Policy
    if algorithm == "QR-DQN":
        from sb3_contrib.qrdqn.policies import QRDQNPolicy

        return QRDQNPolicy
    if algorithm == "TQC":
        from sb3_contrib.tqc.policies import TQCPolicy

        return TQCPolicy
    from sb3_contrib.ars.policies import ARSLinearPolicy, ARSPolicy

    return ARSLinearPolicy if linear else ARSPolicy


class _NoOptimizer:
    """Stands in for the optimizer stable-baselines3 builds with every policy."""

    def __init__(self, parameters, lr: float = 0.0, **kwargs: Any) -> None:
        pass


def _no_learning(_progress: float) -> float:
    return 0.0


def _linear(layer) -> tuple[np.ndarray, np.ndarray]:
    weight_t = np.ascontiguousarray(layer.weight.detach().numpy().T)
    if layer.bias is None:  # ARS's linear policy
        return weight_t, np.zeros(weight_t.shape[1], dtype=np.float32)
    return weight_t, layer.bias.detach().numpy().copy()


def _linears(sequential) -> list[tuple[np.ndarray, np.ndarray]]:
    import torch

    if isinstance(sequential, torch.nn.Linear):
        return [_linear(sequential)]
    return [_linear(layer) for layer in sequential if isinstance(layer, torch.nn.Linear)]


def _hardtanh_bound(module) -> float | None:
    """SAC's and TQC's clip of their mean under gSDE (a Hardtanh after `mu`), if any."""
    import torch

    for layer in module.modules():
        if isinstance(layer, torch.nn.Hardtanh):
            return float(layer.max_val)
    return None


# -- reading the zip ------------------------------------------------------------


def read_sb3_zip(path: str | Path) -> SB3Policy:
    """Read a stable-baselines3 zip safely; `PolicyError` (or `RefusedForSafety`) if not."""
    path = Path(path)
    content = read_file(path, MAX_FILE_BYTES, "a stable-baselines3 .zip")
    sha256 = hashlib.sha256(content).hexdigest()
    archive = Archive(path, content, MEMBER_LIMITS, required=("data", "policy.pth"))
    data = _parse_data(path, archive.read("data"))
    algorithm, linear = _algorithm(path, data)
    _check_keys(path, data)
    version = "unknown"
    if "_stable_baselines3_version" in archive:
        raw = archive.read("_stable_baselines3_version")
        version = raw.decode("ascii", "replace").strip()[:32]
    observation_shape = _observation_shape(path, data["observation_space"])
    action_space = _action_space(path, data["action_space"])
    kwargs = _policy_kwargs(path, data.get("policy_kwargs", {}))
    family = ALGORITHMS[algorithm].family
    if family == "q" and not isinstance(action_space, spaces.Discrete):
        raise PolicyError(f"{path}: a {algorithm} policy with a {action_space} action space")
    if family in ("sac", "td3") and not isinstance(action_space, spaces.Box):
        raise PolicyError(f"{path}: a {algorithm} policy with a {action_space} action space")
    use_sde = data.get("use_sde", False)
    if not isinstance(use_sde, bool):
        raise PolicyError(f"{path}: use_sde must be true or false, got {use_sde!r}")
    use_sde = use_sde or bool(kwargs.get("use_sde"))
    if algorithm == "QR-DQN" and "n_quantiles" not in kwargs:
        kwargs["n_quantiles"] = _integer(path, data, "n_quantiles", 200, _MAX_QUANTILES)
    if linear and ("net_arch" in kwargs or "activation" in kwargs):
        raise PolicyError(f"{path}: ARS's LinearPolicy takes no net_arch or activation_fn")
    exploration_rate = 0.0
    if family == "q":
        exploration_rate = data.get("exploration_rate", 0.0)
        if not isinstance(exploration_rate, int | float) or not 0.0 <= exploration_rate <= 1.0:
            raise PolicyError(f"{path}: exploration_rate must be a number in [0, 1]")
    declared = declared_parameters(
        algorithm,
        observation_shape,
        action_space,
        [] if linear else kwargs.get("net_arch"),
        kwargs,
        use_sde,
    )
    if declared > MAX_PARAMETERS:
        raise RefusedForSafety(
            f"{path}: its {algorithm} network (net_arch {kwargs.get('net_arch', 'default')}) "
            f"has {declared:,} parameters, more than the {MAX_PARAMETERS:,} bbbench evaluates"
        )
    weights = read_weights(path, archive.read("policy.pth"))
    return SB3Policy(
        name=path.name,
        sha256=sha256,
        algorithm=algorithm,
        observation_shape=observation_shape,
        action_space=action_space,
        net_arch=kwargs.pop("net_arch", None),
        activation=kwargs.pop("activation", None),
        architecture=kwargs,
        exploration_rate=float(exploration_rate),
        weights=weights,
        sb3_version=version,
        use_sde=use_sde,
        vecnormalize=trained_in_vecnormalize(family, data),
        linear=linear,
    )


def trained_in_vecnormalize(family: str, data: dict[str, Any]) -> bool | None:
    """Whether the zip's plain data shows training inside VecNormalize.

    stable-baselines3 keeps `_last_original_obs` (the last observation before
    normalization) only under VecNormalize on on-policy algorithms (PPO, A2C,
    TRPO): there a value means VecNormalize, null means none. Off-policy
    algorithms (DQN, SAC, TD3, QR-DQN, TQC) also keep it without VecNormalize (the
    observation before the last step): a value there cannot tell (None).
    """
    if data.get("_last_original_obs") is None:
        return False
    return True if family == "actor_critic" else None


def _parse_data(path: Path, raw: bytes) -> dict[str, Any]:
    try:
        data = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise PolicyError(f"{path}: its 'data' member is not JSON ({error})") from None
    except RecursionError:
        raise PolicyError(
            f"{path}: its 'data' member nests too deeply to be a model.save() file"
        ) from None
    if not isinstance(data, dict):
        raise PolicyError(f"{path}: its 'data' member is not a JSON object")
    if _depth(data) > _MAX_JSON_DEPTH:
        raise PolicyError(
            f"{path}: its 'data' member nests more than {_MAX_JSON_DEPTH} levels deep; "
            f"not a model.save() file"
        )
    for key in ("policy_class", "observation_space", "action_space"):
        if key not in data:
            raise PolicyError(f"{path}: 'data' has no {key!r}; is it a model.save() file?")
    return data


def _depth(value: Any) -> int:
    """How deeply JSON containers nest (iteratively: no recursion limit to hit)."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict | list):
            deepest = max(deepest, depth)
            if depth <= _MAX_JSON_DEPTH:
                stack.extend(
                    (v, depth + 1) for v in (item.values() if isinstance(item, dict) else item)
                )
    return deepest


def _check_keys(path: Path, data: dict[str, Any]) -> None:
    unknown = sorted(set(data) - _PICKLED_BY_SB3 - _PLAIN)
    if unknown:
        raise RefusedForSafety(
            f"{path}: 'data' has entries stable-baselines3 does not write: {unknown}"
        )
    for key, value in data.items():
        if key not in _PICKLED_BY_SB3 and _pickled(value):
            raise RefusedForSafety(
                f"{path}: 'data' entry {key!r} holds pickled content (':serialized:') where "
                f"plain data is expected; bbbench never unpickles a submitted file"
            )


def _pickled(value: Any) -> bool:
    stack = [value]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            if ":serialized:" in item:
                return True
            stack.extend(item.values())
        elif isinstance(item, list):
            stack.extend(item)
    return False


def class_reference(serialized: Any) -> tuple[str, str] | None:
    """(module, name) if `serialized` (base64) is exactly the pickle of a class saved by
    reference, as stable-baselines3 writes a policy class; None for anything else. Read
    byte by byte: nothing is unpickled."""
    if not isinstance(serialized, str) or len(serialized) > 1024:
        return None
    try:
        raw = base64.b64decode(serialized, validate=True)
    except (binascii.Error, ValueError):
        return None
    # PROTO 4 or 5, FRAME <length>, then two SHORT_BINUNICODE + MEMOIZE, STACK_GLOBAL,
    # MEMOIZE, STOP.
    if len(raw) < 11 or raw[0] != 0x80 or raw[1] not in (4, 5) or raw[2] != 0x95:
        return None
    if int.from_bytes(raw[3:11], "little") != len(raw) - 11:
        return None
    body, texts = raw[11:], []
    for _ in range(2):
        if len(body) < 2 or body[0] != 0x8C:
            return None
        length = body[1]
        text, body = body[2 : 2 + length], body[2 + length :]
        if len(text) != length or body[:1] != b"\x94":
            return None
        try:
            texts.append(text.decode("utf-8"))
        except UnicodeDecodeError:
            return None
        body = body[1:]
    if body != b"\x93\x94.":
        return None
    module, name = texts
    return module, name


def _algorithm(path: Path, data: dict[str, Any]) -> tuple[str, bool]:
    """The algorithm, and whether its policy is ARS's LinearPolicy."""
    entry = data["policy_class"]
    reference = class_reference(entry.get(":serialized:")) if isinstance(entry, dict) else None
    if reference is None:
        if isinstance(entry, dict) and ":serialized:" in entry:
            raise RefusedForSafety(
                f"{path}: 'policy_class' is pickled content that is not a plain reference to "
                f"a class; bbbench never unpickles a submitted file"
            )
        raise PolicyError(f"{path}: 'policy_class' is not a stable-baselines3 policy class")
    module, name = reference
    supported = ", ".join(ALGORITHMS)
    if reference not in _POLICY_CLASSES:
        what = next((label for marker, label in _UNSUPPORTED if marker in name), f"{module}.{name}")
        raise PolicyError(
            f"{path}: algorithm {what} is not supported: bbbench evaluates the MLP policies "
            f"of {supported}"
        )
    algorithms = _POLICY_CLASSES[reference]
    if len(algorithms) == 1:
        return algorithms[0], name == "ARSLinearPolicy"
    if "cg_max_steps" in data:
        return "TRPO", False
    return ("PPO" if "n_epochs" in data else "A2C"), False


def _observation_shape(path: Path, entry: Any) -> tuple[int, ...]:
    if not isinstance(entry, dict) or entry.get(":type:") != _BOX_TYPE:
        kind = entry.get(":type:") if isinstance(entry, dict) else type(entry).__name__
        raise PolicyError(f"{path}: observation space {kind}; bbbench policies observe a Box")
    return _shape(path, entry, "observation")


def _shape(path: Path, entry: dict[str, Any], what: str) -> tuple[int, ...]:
    shape = entry.get("_shape")
    if (
        not isinstance(shape, list)
        or not shape
        or len(shape) > 4
        or not all(isinstance(n, int) and not isinstance(n, bool) for n in shape)
        or not all(0 < n <= _MAX_WIDTH for n in shape)
        or math.prod(shape) > _MAX_WIDTH
    ):
        raise PolicyError(f"{path}: unreadable {what} space shape {shape!r}")
    return tuple(shape)


def _numbers(path: Path, text: Any, what: str) -> np.ndarray:
    """'[-1.  2.]', as numpy prints a bound in SB3's plain fields, to float32."""
    if not isinstance(text, str) or len(text) > 4096:
        raise PolicyError(f"{path}: unreadable Box {what} bound {text!r}")
    try:
        return np.array([float(x) for x in text.strip("[]").split()], dtype=np.float32)
    except ValueError:
        raise PolicyError(f"{path}: unreadable Box {what} bound {text!r}") from None


def _action_space(path: Path, entry: Any) -> spaces.Discrete | spaces.Box:
    kind = entry.get(":type:") if isinstance(entry, dict) else None
    if kind == _DISCRETE_TYPE:
        n, start = str(entry.get("n")), str(entry.get("start", "0"))
        if not _DIGITS.fullmatch(n) or not 0 < int(n) <= _MAX_WIDTH or start != "0":
            raise PolicyError(
                f"{path}: unreadable Discrete action space (n={n!r}, start={start!r}); "
                f"expected n a whole number in 1..{_MAX_WIDTH} and start 0"
            )
        return spaces.Discrete(int(n))
    if kind == _BOX_TYPE:
        shape = _shape(path, entry, "action")
        low = _numbers(path, entry.get("low"), "low")
        high = _numbers(path, entry.get("high"), "high")
        if low.size != math.prod(shape) or high.size != math.prod(shape):
            raise PolicyError(f"{path}: Box action bounds do not match its shape {shape}")
        if not (np.isfinite(low).all() and np.isfinite(high).all() and (low <= high).all()):
            raise PolicyError(
                f"{path}: Box action bounds must be finite with low <= high, got low={low} "
                f"high={high}"
            )
        return spaces.Box(low.reshape(shape), high.reshape(shape), dtype=np.float32)
    raise PolicyError(
        f"{path}: action space {kind or type(entry).__name__}; bbbench tasks act in Discrete or Box"
    )


def _integer(path: Path, entries: dict, key: str, default: int, most: int) -> int:
    value = entries.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= most:
        raise PolicyError(f"{path}: {key} must be a whole number in 1..{most}, got {value!r}")
    return value


def _policy_kwargs(path: Path, entry: Any) -> dict[str, Any]:
    """The architecture, from the plain fields of policy_kwargs (SB3 writes them beside
    the pickled value when a kwarg, such as activation_fn, is not plain JSON)."""
    if not isinstance(entry, dict):
        raise PolicyError(f"{path}: policy_kwargs must be a JSON object")
    plain = {key: value for key, value in entry.items() if not key.startswith(":")}
    if ":serialized:" in entry and entry.get(":type:") != "<class 'dict'>":
        raise RefusedForSafety(f"{path}: policy_kwargs is pickled content that is not a dict")
    known = set(_ARCHITECTURE_KWARGS) | set(_TRAINING_ONLY_KWARGS)
    unknown = sorted(set(plain) - known)
    if unknown:
        raise PolicyError(
            f"{path}: unsupported policy_kwargs {unknown}; bbbench rebuilds MLP policies from "
            f"{list(_ARCHITECTURE_KWARGS)} only"
        )
    kwargs: dict[str, Any] = {}
    if "net_arch" in plain and plain["net_arch"] is not None:
        kwargs["net_arch"] = _net_arch(path, plain["net_arch"])
    if "activation_fn" in plain:
        match = _ACTIVATION_REPR.fullmatch(str(plain["activation_fn"]))
        if not match or match.group(1) not in ACTIVATIONS:
            raise PolicyError(
                f"{path}: activation_fn {plain['activation_fn']!r} is not one of "
                f"torch.nn.{', torch.nn.'.join(ACTIVATIONS)}"
            )
        kwargs["activation"] = match.group(1)
    if "n_critics" in plain:
        kwargs["n_critics"] = _integer(path, plain, "n_critics", 2, _MAX_CRITICS)
    if "n_quantiles" in plain:
        kwargs["n_quantiles"] = _integer(path, plain, "n_quantiles", 25, _MAX_QUANTILES)
    flags = ("share_features_extractor", "use_sde", "squash_output", "with_bias", "full_std")
    for key in (*flags, "use_expln"):
        if key in plain:
            if not isinstance(plain[key], bool):
                raise PolicyError(f"{path}: policy_kwargs {key} must be true or false")
            kwargs[key] = plain[key]
    if "clip_mean" in plain:
        clip_mean = plain["clip_mean"]
        if isinstance(clip_mean, bool) or not isinstance(clip_mean, int | float):
            raise PolicyError(f"{path}: policy_kwargs clip_mean must be a number")
        if not 0.0 <= clip_mean <= 1e6:
            raise PolicyError(f"{path}: policy_kwargs clip_mean must be in [0, 1e6]")
        kwargs["clip_mean"] = float(clip_mean)
    return kwargs


def _net_arch(path: Path, net_arch: Any) -> list[int] | dict[str, list[int]]:
    def layers(value: Any) -> list[int]:
        if (
            not isinstance(value, list)
            or len(value) > _MAX_LAYERS
            or not all(isinstance(n, int) and not isinstance(n, bool) for n in value)
            or not all(0 < n <= _MAX_WIDTH for n in value)
        ):
            raise PolicyError(
                f"{path}: net_arch {net_arch!r}: expected up to {_MAX_LAYERS} layer widths "
                f"in 1..{_MAX_WIDTH}"
            )
        return value

    if isinstance(net_arch, dict):
        if not net_arch or not set(net_arch) <= {"pi", "vf", "qf"}:
            raise PolicyError(f"{path}: net_arch {net_arch!r}: keys must be pi, vf or qf")
        return {key: layers(value) for key, value in net_arch.items()}
    return layers(net_arch)


def _mlp_parameters(inputs: int, layers: list[int], outputs: int) -> int:
    """Weights and biases of Linear layers inputs -> layers... -> outputs (0: no head)."""
    widths = [inputs, *layers, *([outputs] if outputs else [])]
    return sum(a * b + b for a, b in itertools.pairwise(widths))


def declared_parameters(
    algorithm: str,
    observation_shape: tuple[int, ...],
    action_space: spaces.Space,
    net_arch: list[int] | dict[str, list[int]] | None,
    kwargs: dict[str, Any],
    use_sde: bool = False,
) -> int:
    """The parameters of the network stable-baselines3 would build for this algorithm and
    architecture (critics and target networks included), counted without building it."""
    family = ALGORITHMS[algorithm].family
    default = list(ALGORITHMS[algorithm].net_arch)
    if net_arch is None:
        net_arch = default
    pi = net_arch.get("pi", default) if isinstance(net_arch, dict) else net_arch
    vf = net_arch.get("vf", default) if isinstance(net_arch, dict) else net_arch
    qf = net_arch.get("qf", default) if isinstance(net_arch, dict) else net_arch
    observations = math.prod(observation_shape)
    discrete = isinstance(action_space, spaces.Discrete)
    actions = int(action_space.n) if discrete else math.prod(action_space.shape)
    if family == "actor_critic":
        latent_pi, latent_vf = (pi or [observations])[-1], (vf or [observations])[-1]
        log_std = 0 if discrete else latent_pi * actions if use_sde else actions
        return (
            _mlp_parameters(observations, pi, 0)
            + _mlp_parameters(observations, vf, 0)
            + _mlp_parameters(latent_pi, [], actions)
            + _mlp_parameters(latent_vf, [], 1)
            + log_std
        )
    if family == "q":
        outputs = actions * kwargs.get("n_quantiles", 1)
        return 2 * _mlp_parameters(observations, pi, outputs)  # the network and its target
    critics = kwargs.get("n_critics", 2)
    if family == "sac":
        latent = (pi or [observations])[-1]
        quantiles = kwargs.get("n_quantiles", 25) if algorithm == "TQC" else 1
        actor = _mlp_parameters(observations, pi, 0) + 2 * _mlp_parameters(latent, [], actions)
        critic = critics * _mlp_parameters(observations + actions, qf, quantiles)
        return actor + 2 * critic
    if family == "td3":
        actor = _mlp_parameters(observations, pi, actions)
        critic = critics * _mlp_parameters(observations + actions, qf, 1)
        return 2 * (actor + critic)
    return _mlp_parameters(observations, pi, actions)  # ARS
