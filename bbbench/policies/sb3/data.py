"""The `data` member of a stable-baselines3 zip, read as plain JSON and never unpickled
(`bbbench.policies.sb3.reader` says why): its keys, its policy class as a plain class
reference, its spaces and its policy kwargs, each checked, each refusal a `PolicyError`
that names the file."""

from __future__ import annotations

import base64
import binascii
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from bbbench.policies.errors import PolicyError, RefusedForSafety
from bbbench.policies.mlp import ACTIVATIONS
from bbbench.policies.sb3.algorithms import SB3_ALGORITHMS, Algorithm, algorithm_of

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
MAX_QUANTILES, _MAX_CRITICS = 1000, 8
_ACTIVATION_REPR = re.compile(r"<class 'torch\.nn\.modules\.activation\.(\w+)'>")
_BOX_TYPE = "<class 'gymnasium.spaces.box.Box'>"
_DISCRETE_TYPE = "<class 'gymnasium.spaces.discrete.Discrete'>"
_DIGITS = re.compile(r"[0-9]{1,9}")


def parse_data(path: Path, raw: bytes) -> dict[str, Any]:
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


def check_keys(path: Path, data: dict[str, Any]) -> None:
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


def algorithm_and_class(path: Path, data: dict[str, Any]) -> tuple[Algorithm, str]:
    """The algorithm, and the policy class ("module:Name") the zip names."""
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
    algorithm = algorithm_of(f"{module}:{name}", data)
    if algorithm is None:
        what = next((label for marker, label in _UNSUPPORTED if marker in name), f"{module}.{name}")
        raise PolicyError(
            f"{path}: algorithm {what} is not supported: bbbench evaluates the MLP policies "
            f"of {', '.join(SB3_ALGORITHMS)}"
        )
    return algorithm, f"{module}:{name}"


def observation_shape(path: Path, entry: Any) -> tuple[int, ...]:
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


def read_action_space(path: Path, entry: Any) -> spaces.Discrete | spaces.Box:
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


def integer(path: Path, entries: dict, key: str, default: int, most: int) -> int:
    value = entries.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= most:
        raise PolicyError(f"{path}: {key} must be a whole number in 1..{most}, got {value!r}")
    return value


def policy_kwargs(path: Path, entry: Any) -> dict[str, Any]:
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
        kwargs["n_critics"] = integer(path, plain, "n_critics", 2, _MAX_CRITICS)
    if "n_quantiles" in plain:
        kwargs["n_quantiles"] = integer(path, plain, "n_quantiles", 25, MAX_QUANTILES)
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
