"""Read a stable-baselines3 `.zip` without trusting it.

stable-baselines3's own `load` unpickles the `:serialized:` values of the zip's
`data` member, so a crafted file runs code during `PPO.load`. This module never
calls it (nor `BasePolicy.load`, nor `pickle`) on a submitted file:

1. The zip's member names are allowlisted and each member's size is capped
   before it is inflated; reading stops at the cap, whatever the header claims.
2. `data` is read as plain JSON. Only the keys where stable-baselines3 itself
   pickles (spaces, schedules, buffers...) may hold `:serialized:` values, and
   those values are never decoded: bbbench reads the plain fields SB3 writes
   beside them. `policy_class` must be, byte for byte, a reference to one of
   SB3's MLP policy classes. Any other key, or pickled content where plain data
   is expected, refuses the file.
3. `policy.pth` is read with `torch.load(weights_only=True)`.
4. The network is rebuilt from the task's own spaces and an allowlisted
   architecture (`net_arch`, activation by name, from the plain `policy_kwargs`,
   else SB3's defaults), and the weights are loaded with `strict=True`.

Supported: PPO, A2C, DQN, SAC and TD3 with MLP policies, on Box observations.
"""

from __future__ import annotations

import base64
import dataclasses
import hashlib
import io
import json
import re
import struct
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from bbbench.policies.base import PolicyError, RefusedForSafety
from bbbench.policies.mlp import ACTIVATIONS, MlpActor

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

# The attributes stable-baselines3 2.x saves in `data` for the five algorithms.
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
        "target_entropy",
        "target_noise_clip",
        "target_policy_noise",
        "target_update_interval",
        "tau",
        "tensorboard_log",
        "use_sde",
        "use_sde_at_warmup",
        "verbose",
        "vf_coef",
    }
)

# The MLP policy class of each algorithm, as `policy_class` names it.
_POLICY_CLASSES = {
    ("stable_baselines3.common.policies", "ActorCriticPolicy"): ("PPO", "A2C"),
    ("stable_baselines3.dqn.policies", "DQNPolicy"): ("DQN",),
    ("stable_baselines3.sac.policies", "SACPolicy"): ("SAC",),
    ("stable_baselines3.td3.policies", "TD3Policy"): ("TD3",),
}
ALGORITHMS = ("PPO", "A2C", "DQN", "SAC", "TD3")
# stable-baselines3's default activation_fn of each algorithm's MLP policy.
_DEFAULT_ACTIVATION = {"PPO": "Tanh", "A2C": "Tanh", "DQN": "ReLU", "SAC": "ReLU", "TD3": "ReLU"}

# policy_kwargs bbbench understands. The first group shapes the network; the
# second only matters for training (or for options that must be off).
_PASSED_THROUGH_KWARGS = ("n_critics", "share_features_extractor")  # to the policy class as given
_ARCHITECTURE_KWARGS = ("net_arch", "activation_fn", *_PASSED_THROUGH_KWARGS)
_TRAINING_ONLY_KWARGS = (
    "ortho_init",
    "log_std_init",
    "optimizer_class",
    "optimizer_kwargs",
    "normalize_images",
    "use_expln",
    "clip_mean",
    "full_std",
)
_MUST_BE_FALSE_KWARGS = ("use_sde", "squash_output")
_MAX_LAYERS, _MAX_WIDTH = 8, 4096
_ACTIVATION_REPR = re.compile(r"<class 'torch\.nn\.modules\.activation\.(\w+)'>")
_BOX_TYPE = "<class 'gymnasium.spaces.box.Box'>"
_DISCRETE_TYPE = "<class 'gymnasium.spaces.discrete.Discrete'>"


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
    architecture: dict[str, Any]  # n_critics / share_features_extractor, if given
    exploration_rate: float  # DQN's epsilon when acting stochastically; else 0
    weights: dict[str, np.ndarray]  # policy.pth, as numpy arrays
    sb3_version: str

    @property
    def action_mode(self) -> str:
        return "discrete" if isinstance(self.action_space, spaces.Discrete) else "continuous"

    def torch_policy(self, observation_space: spaces.Box, action_space: spaces.Space):
        """stable-baselines3's own policy module for these spaces, weights loaded strictly."""
        import torch
        from stable_baselines3.common.policies import ActorCriticPolicy
        from stable_baselines3.dqn.policies import DQNPolicy
        from stable_baselines3.sac.policies import SACPolicy
        from stable_baselines3.td3.policies import TD3Policy

        classes = {
            "PPO": ActorCriticPolicy,
            "A2C": ActorCriticPolicy,
            "DQN": DQNPolicy,
            "SAC": SACPolicy,
            "TD3": TD3Policy,
        }
        # An optimizer is for training; building torch's Adam costs over a second.
        kwargs = {**self.architecture, "optimizer_class": _NoOptimizer}
        if self.net_arch is not None:
            kwargs["net_arch"] = self.net_arch
        if self.activation is not None:
            kwargs["activation_fn"] = getattr(torch.nn, self.activation)
        try:
            policy = classes[self.algorithm](
                observation_space, action_space, lr_schedule=lambda _: 0.0, **kwargs
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
        activation = self.activation or _DEFAULT_ACTIVATION[self.algorithm]
        if self.algorithm in ("PPO", "A2C"):
            hidden = _linears(policy.mlp_extractor.policy_net)
            head = _linear(policy.action_net)
            if isinstance(action_space, spaces.Discrete):
                output, log_std = "argmax", None
            else:
                output, log_std = "gaussian", policy.log_std.detach().numpy().copy()
        elif self.algorithm == "DQN":
            *hidden, head = _linears(policy.q_net.q_net)
            output, log_std = "argmax", None
        elif self.algorithm == "SAC":
            hidden = _linears(policy.actor.latent_pi)
            head = _linear(policy.actor.mu)
            output, log_std = "squashed_gaussian", _linear(policy.actor.log_std)
        else:  # TD3: its last layer is followed by tanh
            *hidden, head = _linears(policy.actor.mu)
            output, log_std = "tanh", None
        box = isinstance(action_space, spaces.Box)
        return MlpActor(
            hidden=tuple(hidden),
            activation=activation,
            head=head,
            output=output,
            log_std=log_std,
            epsilon=self.exploration_rate,
            low=action_space.low.copy() if box else None,
            high=action_space.high.copy() if box else None,
        )


class _NoOptimizer:
    """Stands in for the optimizer stable-baselines3 builds with every policy."""

    def __init__(self, parameters, lr: float = 0.0, **kwargs: Any) -> None:
        pass


def _linear(layer) -> tuple[np.ndarray, np.ndarray]:
    return (
        np.ascontiguousarray(layer.weight.detach().numpy().T),
        layer.bias.detach().numpy().copy(),
    )


def _linears(sequential) -> list[tuple[np.ndarray, np.ndarray]]:
    import torch

    return [_linear(layer) for layer in sequential if isinstance(layer, torch.nn.Linear)]


# -- reading the zip ------------------------------------------------------------


def read_sb3_zip(path: str | Path) -> SB3Policy:
    """Read a stable-baselines3 zip safely; `PolicyError` (or `RefusedForSafety`) if not."""
    path = Path(path)
    name = path.name
    if not path.exists():
        raise PolicyError(f"{path}: no such file")
    if not path.is_file():
        raise PolicyError(f"{path}: not a file (expected a stable-baselines3 .zip)")
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise RefusedForSafety(f"{path}: {size} bytes, more than the {MAX_FILE_BYTES} allowed")
    content = path.read_bytes()
    sha256 = hashlib.sha256(content).hexdigest()
    try:
        archive = zipfile.ZipFile(io.BytesIO(content))
        members = archive.infolist()
    except (zipfile.BadZipFile, EOFError, ValueError) as error:
        raise PolicyError(
            f"{path}: not a readable zip ({error}); expected a stable-baselines3 model saved "
            f"with model.save()"
        ) from None
    _check_members(path, members)
    data = _parse_data(path, _read_member(path, archive, "data"))
    weights = _read_weights(path, _read_member(path, archive, "policy.pth"))
    version = "unknown"
    if "_stable_baselines3_version" in archive.namelist():
        raw = _read_member(path, archive, "_stable_baselines3_version")
        version = raw.decode("ascii", "replace").strip()[:32]
    algorithm = _algorithm(path, data)
    observation_shape = _observation_shape(path, data["observation_space"])
    action_space = _action_space(path, data["action_space"])
    kwargs = _policy_kwargs(path, data.get("policy_kwargs", {}))
    if algorithm == "DQN" and not isinstance(action_space, spaces.Discrete):
        raise PolicyError(f"{path}: a DQN policy with a {action_space} action space")
    if algorithm in ("SAC", "TD3") and not isinstance(action_space, spaces.Box):
        raise PolicyError(f"{path}: a {algorithm} policy with a {action_space} action space")
    exploration_rate = 0.0
    if algorithm == "DQN":
        exploration_rate = data.get("exploration_rate", 0.0)
        if not isinstance(exploration_rate, int | float) or not 0.0 <= exploration_rate <= 1.0:
            raise PolicyError(f"{path}: exploration_rate must be a number in [0, 1]")
    return SB3Policy(
        name=name,
        sha256=sha256,
        algorithm=algorithm,
        observation_shape=observation_shape,
        action_space=action_space,
        net_arch=kwargs.get("net_arch"),
        activation=kwargs.get("activation"),
        architecture={
            k: kwargs[k] for k in ("n_critics", "share_features_extractor") if k in kwargs
        },
        exploration_rate=float(exploration_rate),
        weights=weights,
        sb3_version=version,
    )


def _check_members(path: Path, members: list[zipfile.ZipInfo]) -> None:
    names = [member.filename for member in members]
    for required in ("data", "policy.pth"):
        if required not in names:
            raise PolicyError(
                f"{path}: no {required!r} member; expected a complete stable-baselines3 "
                f"model.save() file (is it truncated?)"
            )
    unexpected = sorted(set(names) - set(MEMBER_LIMITS))
    if unexpected:
        raise RefusedForSafety(
            f"{path}: unexpected member(s) {unexpected} in the zip; a stable-baselines3 model "
            f"holds only {sorted(MEMBER_LIMITS)}"
        )
    if len(set(names)) != len(names):
        raise RefusedForSafety(f"{path}: the zip names a member twice")
    for member in members:
        limit = MEMBER_LIMITS[member.filename]
        if member.file_size > limit:
            raise RefusedForSafety(
                f"{path}: member {member.filename!r} inflates to {member.file_size} bytes, "
                f"more than the {limit} allowed (a zip bomb?)"
            )


def _read_member(path: Path, archive: zipfile.ZipFile, name: str) -> bytes:
    """A member's bytes, inflating at most its limit whatever its header claims."""
    limit = MEMBER_LIMITS[name]
    try:
        with archive.open(name) as stream:
            content = stream.read(limit + 1)
    except (zipfile.BadZipFile, EOFError, zlib.error, ValueError, NotImplementedError) as error:
        raise PolicyError(
            f"{path}: cannot read {name!r} from the zip ({error}); truncated?"
        ) from None
    if len(content) > limit:
        raise RefusedForSafety(
            f"{path}: member {name!r} inflates to more than the {limit} bytes allowed (a zip bomb?)"
        )
    return content


def _parse_data(path: Path, raw: bytes) -> dict[str, Any]:
    try:
        data = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise PolicyError(f"{path}: its 'data' member is not JSON ({error})") from None
    if not isinstance(data, dict):
        raise PolicyError(f"{path}: its 'data' member is not a JSON object")
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
    for key in ("policy_class", "observation_space", "action_space"):
        if key not in data:
            raise PolicyError(f"{path}: 'data' has no {key!r}; is it a model.save() file?")
    return data


def _pickled(value: Any) -> bool:
    if isinstance(value, dict):
        return ":serialized:" in value or any(_pickled(item) for item in value.values())
    if isinstance(value, list):
        return any(_pickled(item) for item in value)
    return False


def _class_reference(module: str, name: str) -> str:
    """base64 of the pickle SB3 writes for a class saved by reference (protocol 5)."""
    body = b""
    for text in (module.encode(), name.encode()):
        body += b"\x8c" + bytes([len(text)]) + text + b"\x94"
    body += b"\x93\x94."
    return base64.b64encode(b"\x80\x05\x95" + struct.pack("<Q", len(body)) + body).decode()


def _algorithm(path: Path, data: dict[str, Any]) -> str:
    entry = data["policy_class"]
    module = entry.get("__module__") if isinstance(entry, dict) else None
    for (known_module, class_name), algorithms in _POLICY_CLASSES.items():
        if module == known_module and entry.get(":serialized:") == _class_reference(
            known_module, class_name
        ):
            if len(algorithms) == 1:
                return algorithms[0]
            return "PPO" if "n_epochs" in data else "A2C"
    if isinstance(entry, dict) and ":serialized:" in entry:
        raise RefusedForSafety(
            f"{path}: 'policy_class' is pickled content that is not a plain reference to one "
            f"of stable-baselines3's MLP policy classes ({', '.join(ALGORITHMS)}); bbbench "
            f"never unpickles a submitted file"
        )
    raise PolicyError(
        f"{path}: unsupported policy class {module!r}: bbbench evaluates MLP policies of "
        f"{', '.join(ALGORITHMS)}"
    )


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
        or not all(isinstance(n, int) and 0 < n <= _MAX_WIDTH for n in shape)
    ):
        raise PolicyError(f"{path}: unreadable {what} space shape {shape!r}")
    return tuple(shape)


def _numbers(path: Path, text: Any) -> np.ndarray:
    """'[-1.  2.]', as numpy prints a bound in SB3's plain fields, to float32."""
    if not isinstance(text, str) or len(text) > 4096:
        raise PolicyError(f"{path}: unreadable Box bound {text!r}")
    try:
        return np.array([float(x) for x in text.strip("[]").split()], dtype=np.float32)
    except ValueError:
        raise PolicyError(f"{path}: unreadable Box bound {text!r}") from None


def _action_space(path: Path, entry: Any) -> spaces.Discrete | spaces.Box:
    kind = entry.get(":type:") if isinstance(entry, dict) else None
    if kind == _DISCRETE_TYPE:
        n, start = str(entry.get("n")), str(entry.get("start", "0"))
        if not n.isdigit() or not 0 < int(n) <= _MAX_WIDTH or start != "0":
            raise PolicyError(f"{path}: unreadable Discrete action space (n={n}, start={start})")
        return spaces.Discrete(int(n))
    if kind == _BOX_TYPE:
        shape = _shape(path, entry, "action")
        low, high = _numbers(path, entry.get("low")), _numbers(path, entry.get("high"))
        if low.size != np.prod(shape) or high.size != np.prod(shape):
            raise PolicyError(f"{path}: Box action bounds do not match its shape {shape}")
        return spaces.Box(low.reshape(shape), high.reshape(shape), dtype=np.float32)
    raise PolicyError(
        f"{path}: action space {kind or type(entry).__name__}; bbbench tasks act in Discrete or Box"
    )


def _policy_kwargs(path: Path, entry: Any) -> dict[str, Any]:
    """The architecture, from the plain fields of policy_kwargs (SB3 writes them beside
    the pickled value when a kwarg, such as activation_fn, is not plain JSON)."""
    if not isinstance(entry, dict):
        raise PolicyError(f"{path}: policy_kwargs must be a JSON object")
    plain = {key: value for key, value in entry.items() if not key.startswith(":")}
    if ":serialized:" in entry and entry.get(":type:") != "<class 'dict'>":
        raise RefusedForSafety(f"{path}: policy_kwargs is pickled content that is not a dict")
    known = set(_ARCHITECTURE_KWARGS) | set(_TRAINING_ONLY_KWARGS) | set(_MUST_BE_FALSE_KWARGS)
    unknown = sorted(set(plain) - known)
    if unknown:
        raise PolicyError(
            f"{path}: unsupported policy_kwargs {unknown}; bbbench rebuilds MLP policies from "
            f"{list(_ARCHITECTURE_KWARGS)} only"
        )
    for key in _MUST_BE_FALSE_KWARGS:
        if plain.get(key, False) is not False:
            raise PolicyError(f"{path}: policy_kwargs {key}={plain[key]!r} is not supported")
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
        if not isinstance(plain["n_critics"], int) or not 1 <= plain["n_critics"] <= 8:
            raise PolicyError(f"{path}: n_critics must be an integer in [1, 8]")
        kwargs["n_critics"] = plain["n_critics"]
    if "share_features_extractor" in plain:
        if not isinstance(plain["share_features_extractor"], bool):
            raise PolicyError(f"{path}: share_features_extractor must be true or false")
        kwargs["share_features_extractor"] = plain["share_features_extractor"]
    return kwargs


def _net_arch(path: Path, net_arch: Any) -> list[int] | dict[str, list[int]]:
    def layers(value: Any) -> list[int]:
        if (
            not isinstance(value, list)
            or len(value) > _MAX_LAYERS
            or not all(isinstance(n, int) and 0 < n <= _MAX_WIDTH for n in value)
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


def _read_weights(path: Path, raw: bytes) -> dict[str, np.ndarray]:
    import pickle

    import torch

    try:
        state = torch.load(io.BytesIO(raw), map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as error:
        first = str(error).strip().splitlines()[0] if str(error).strip() else "unpickling"
        raise RefusedForSafety(
            f"{path}: 'policy.pth' holds pickled objects other than tensors, which "
            f"torch.load(weights_only=True) refuses ({first[:200]})"
        ) from None
    except Exception as error:  # torch raises many kinds for a corrupt file
        raise PolicyError(f"{path}: cannot read 'policy.pth' ({type(error).__name__})") from None
    if not isinstance(state, dict) or not all(
        isinstance(key, str) and isinstance(value, torch.Tensor) for key, value in state.items()
    ):
        raise PolicyError(f"{path}: 'policy.pth' is not a state dict of named tensors")
    return {key: value.detach().cpu().numpy().copy() for key, value in state.items()}
