"""stable-baselines3's `VecNormalize` statistics, read without running the file.

A policy trained inside `VecNormalize` (rl-zoo3's `normalize: True`) acts on
normalized observations; without its statistics it is scored on raw ones, and
scored wrong. stable-baselines3 saves them with `VecNormalize.save`, a pickle of
the whole wrapper, which `VecNormalize.load` unpickles: a crafted file runs
code there. bbbench reads it with a restricted unpickler:

- numpy arrays, dtypes and scalars are rebuilt by numpy's own reconstructors;
- the classes of the wrapper and what it holds (`VecNormalize`,
  `RunningMeanStd`, gymnasium spaces, numpy's random generators) become inert
  stand-ins that only record their arguments and state: no stable-baselines3,
  gymnasium or generator code runs;
- any other global refuses the file.

From the stand-ins bbbench takes `norm_obs`, `clip_obs`, `epsilon` and
`obs_rms.mean` / `obs_rms.var`, and normalizes as `VecNormalize.normalize_obs`
does at prediction time: `clip((obs - mean) / sqrt(var + epsilon), -clip_obs,
clip_obs)` in float64, cast to float32.
"""

from __future__ import annotations

import hashlib
import io
import pickle
from pathlib import Path
from typing import Any

import numpy as np

from bbbench.policies.archive import read_file
from bbbench.policies.errors import PolicyError, RefusedForSafety
from bbbench.policies.normalization import ObservationNormalization

MAX_STATISTICS_BYTES = 16 * 2**20
STATISTICS_FILE = "vecnormalize.pkl"  # the name stable-baselines3's docs and rl-zoo3 use

try:
    from numpy._core import multiarray as _multiarray
    from numpy._core import numeric as _numeric
except ImportError:  # numpy < 2
    from numpy.core import multiarray as _multiarray
    from numpy.core import numeric as _numeric

_MAX_ARRAY_ELEMENTS = 2**20


def _reconstruct(subtype: type, shape: Any, dtype: Any) -> np.ndarray:
    """numpy's `_reconstruct` for plain arrays of bounded size (the pickle fills it in)."""
    if subtype is not np.ndarray or np.prod(shape, dtype=np.float64) > _MAX_ARRAY_ELEMENTS:
        raise ValueError(f"an array of shape {shape}: larger than statistics")
    return _multiarray._reconstruct(subtype, shape, dtype)


_NUMPY_RECONSTRUCTORS = {("numpy", "ndarray"): np.ndarray, ("numpy", "dtype"): np.dtype}
for _module in ("numpy.core", "numpy._core"):
    _NUMPY_RECONSTRUCTORS[f"{_module}.multiarray", "_reconstruct"] = _reconstruct
    _NUMPY_RECONSTRUCTORS[f"{_module}.multiarray", "scalar"] = _multiarray.scalar
    _NUMPY_RECONSTRUCTORS[f"{_module}.numeric", "_frombuffer"] = _numeric._frombuffer

# Globals a VecNormalize pickle refers to, made inert.
_STAND_INS = {
    ("stable_baselines3.common.vec_env.vec_normalize", "VecNormalize"),
    ("stable_baselines3.common.running_mean_std", "RunningMeanStd"),
    ("numpy.random._pickle", "__generator_ctor"),
    ("numpy.random._pickle", "__bit_generator_ctor"),
    ("numpy.random._pickle", "__randomstate_ctor"),
    ("numpy.random.bit_generator", "__pyx_unpickle_SeedSequence"),
    ("numpy.random.bit_generator", "SeedSequence"),
    ("collections", "OrderedDict"),
    *(
        ("gymnasium.spaces." + module, name)
        for module, name in (
            ("box", "Box"),
            ("discrete", "Discrete"),
            ("multi_discrete", "MultiDiscrete"),
            ("multi_binary", "MultiBinary"),
            ("dict", "Dict"),
            ("tuple", "Tuple"),
        )
    ),
    *(
        ("numpy.random._" + name.lower(), name)
        for name in ("PCG64", "PCG64DXSM", "MT19937", "Philox", "SFC64")
    ),
}


class StandIn:
    """What a restricted unpickle makes of an allowed class or function: its arguments
    and its state, and nothing else."""

    origin: tuple[str, str]

    def __new__(cls, *args: Any, **kwargs: Any) -> StandIn:
        return super().__new__(cls)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args = args
        self.state: Any = None

    def __setstate__(self, state: Any) -> None:
        self.state = state

    def __setitem__(self, key: Any, value: Any) -> None:  # an OrderedDict's items
        if not isinstance(self.state, dict):
            self.state = {}
        self.state[key] = value


class _Unpickler(pickle.Unpickler):
    def __init__(self, file, path: Path) -> None:
        super().__init__(file)
        self.path = path
        self.stand_ins: dict[tuple[str, str], type] = {}

    def find_class(self, module: str, name: str):
        key = (module, name)
        if key in _NUMPY_RECONSTRUCTORS:
            return _NUMPY_RECONSTRUCTORS[key]
        if key in _STAND_INS:
            if key not in self.stand_ins:
                self.stand_ins[key] = type(name, (StandIn,), {"origin": key})
            return self.stand_ins[key]
        raise RefusedForSafety(
            f"{self.path}: refers to {module}.{name}, which a VecNormalize statistics file "
            f"does not hold; bbbench never unpickles other objects"
        )

    def persistent_load(self, pid: Any):
        raise RefusedForSafety(f"{self.path}: holds persistent references; refused")


def live_statistics(venv: Any) -> ObservationNormalization:
    """A copy of the statistics a live `VecNormalize` applies now (a policy evaluated
    while it trains sees observations as its training env shows them)."""
    return ObservationNormalization(
        file="(in training)",
        sha256="",
        normalize=bool(venv.norm_obs),
        mean=np.array(venv.obs_rms.mean, dtype=np.float64),
        std=np.sqrt(np.asarray(venv.obs_rms.var, dtype=np.float64) + venv.epsilon),
        clip=float(venv.clip_obs),
    )


def read_statistics(
    path: str | Path, observation_shape: tuple[int, ...]
) -> ObservationNormalization:
    """A `VecNormalize.save` file for a policy observing `observation_shape`, read safely;
    `PolicyError` (or `RefusedForSafety`) naming the file otherwise."""
    path = Path(path)
    content = read_file(path, MAX_STATISTICS_BYTES, "a VecNormalize statistics file (.pkl)")
    try:
        root = _Unpickler(io.BytesIO(content), path).load()
    except PolicyError:
        raise
    except Exception as error:  # a corrupt pickle raises many kinds
        raise PolicyError(
            f"{path}: not a readable VecNormalize statistics file ({type(error).__name__}: "
            f"{str(error)[:120]})"
        ) from None
    if not isinstance(root, StandIn) or root.origin[1] != "VecNormalize":
        raise PolicyError(f"{path}: not a VecNormalize.save() file (it holds no VecNormalize)")
    state = root.state if isinstance(root.state, dict) else {}
    rms = state.get("obs_rms")
    if not isinstance(rms, StandIn) or not isinstance(rms.state, dict):
        raise PolicyError(
            f"{path}: its VecNormalize has no observation statistics (obs_rms); a dict "
            f"observation space is not a bbbench policy's"
        )
    normalize = state.get("norm_obs", True)
    if not isinstance(normalize, bool | np.bool_):
        raise PolicyError(f"{path}: norm_obs must be true or false, got {normalize!r}")
    clip = _number(path, state, "clip_obs")
    epsilon = _number(path, state, "epsilon")
    if not clip > 0 or not epsilon >= 0:
        raise PolicyError(f"{path}: clip_obs must be > 0 and epsilon >= 0 ({clip}, {epsilon})")
    mean, var = (_array(path, rms.state, key, observation_shape) for key in ("mean", "var"))
    if (var < 0).any():
        raise PolicyError(f"{path}: obs_rms.var has negative entries")
    return ObservationNormalization(
        file=path.name,
        sha256=hashlib.sha256(content).hexdigest(),
        normalize=bool(normalize),
        mean=mean,
        std=np.sqrt(var + epsilon),
        clip=clip,
    )


def _number(path: Path, state: dict, key: str) -> float:
    value = state.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating):
        raise PolicyError(f"{path}: VecNormalize's {key} must be a number, got {value!r}")
    value = float(value)
    if not np.isfinite(value):
        raise PolicyError(f"{path}: VecNormalize's {key} must be finite, got {value}")
    return value


def _array(path: Path, state: dict, key: str, shape: tuple[int, ...]) -> np.ndarray:
    value = state.get(key)
    if not isinstance(value, np.ndarray) or value.dtype.kind not in "fiu":
        raise PolicyError(f"{path}: obs_rms.{key} must be a numeric array")
    if value.shape != shape:
        raise PolicyError(
            f"{path}: obs_rms.{key} has shape {value.shape}, but the policy observes {shape}: "
            f"statistics from another environment?"
        )
    value = value.astype(np.float64)
    if not np.isfinite(value).all():
        raise PolicyError(f"{path}: obs_rms.{key} is not finite")
    return value


def find_rl_zoo_statistics(policy_path: str | Path) -> Path | None:
    """The statistics rl-zoo3 saved beside a policy, if there is exactly one candidate.

    rl-zoo3 writes a run to `logs/ALGO/ENV_N/`: the final model as `ENV.zip`
    (and `best_model.zip`, checkpoints) and the statistics as
    `ENV/vecnormalize.pkl`. Candidates: `<stem>/vecnormalize.pkl` beside the zip;
    else every `*/vecnormalize.pkl` beside it (used when there is one; several
    are ambiguous: `PolicyError`).
    """
    folder, stem = Path(policy_path).parent, Path(policy_path).stem
    own = folder / stem / STATISTICS_FILE
    if own.is_file():
        return own
    candidates = sorted(p for p in folder.glob(f"*/{STATISTICS_FILE}") if p.is_file())
    if len(candidates) > 1:
        raise PolicyError(
            f"{policy_path}: trained with VecNormalize, and several statistics files lie "
            f"beside it ({', '.join(map(str, candidates[:4]))}): pass the right one with "
            f"--vecnormalize PATH"
        )
    return candidates[0] if candidates else None
