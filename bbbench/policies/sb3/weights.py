"""Reading `policy.pth` from an untrusted zip: tensors only, bounded, float32 out.

- The file must be in torch's zip format with every record stored (as
  `torch.save` writes it): nothing inside inflates, and no record is larger
  than the member bbbench already capped.
- `torch.load(weights_only=True)` rebuilds only tensors and plain containers;
  it runs no code from the file.
- Every tensor's declared shape is checked *before* its values are copied:
  `torch.load` returns views, and a view may declare billions of elements over a
  few bytes of storage (a stride of 0). The parameters of the whole file are
  capped at `MAX_PARAMETERS`.
- Dtypes: float32 is kept; float16, bfloat16 and float64 are cast to float32
  (the precision bbbench evaluates in, as stable-baselines3 does on a float32
  observation); complex, integer, boolean, quantized, sparse and meta tensors
  are refused, since a cast would change what the network computes.
"""

from __future__ import annotations

import io
import math
import pickle
import zipfile
from pathlib import Path

import numpy as np

from bbbench.policies.errors import PolicyError, RefusedForSafety
from bbbench.policies.file_policy import MAX_PARAMETERS
from bbbench.portable import total

CAST_TO_FLOAT32 = ("float16", "bfloat16", "float64")


def read_weights(path: Path, raw: bytes) -> dict[str, np.ndarray]:
    """`policy.pth`'s state dict as float32 numpy arrays; `PolicyError` (naming `path`)
    for anything else."""
    import torch  # lazy: torch, for policy files only

    _check_records(path, raw)
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
    parameters = 0
    for key, tensor in state.items():
        _check_tensor(path, key, tensor)
        parameters += math.prod(tensor.shape)  # the declared shape: nothing is materialized yet
        if parameters > MAX_PARAMETERS:
            raise RefusedForSafety(
                f"{path}: 'policy.pth' declares more than {MAX_PARAMETERS:,} parameters "
                f"(at {key!r}, shape {tuple(tensor.shape)}); bbbench evaluates smaller networks"
            )
    return {key: tensor.detach().to(torch.float32).numpy().copy() for key, tensor in state.items()}


def _check_records(path: Path, raw: bytes) -> None:
    """torch's zip format, every record stored: nothing in it inflates."""
    try:
        records = zipfile.ZipFile(io.BytesIO(raw)).infolist()
    except (zipfile.BadZipFile, EOFError, ValueError, NotImplementedError):
        raise PolicyError(
            f"{path}: 'policy.pth' is not in torch's zip format (torch.save since torch 1.6)"
        ) from None
    compressed = [r.filename for r in records if r.compress_type != zipfile.ZIP_STORED]
    if compressed:
        raise RefusedForSafety(
            f"{path}: 'policy.pth' has compressed records {compressed[:3]}; torch.save stores "
            f"them uncompressed"
        )
    if total(record.file_size for record in records) > len(raw):
        raise PolicyError(f"{path}: 'policy.pth' records claim more bytes than it holds")


def _check_tensor(path: Path, key: str, tensor) -> None:
    import torch  # lazy: torch, for policy files only

    if tensor.layout != torch.strided:
        kind = str(tensor.layout).removeprefix("torch.")
    elif tensor.is_meta:
        kind = "meta (no values)"
    elif tensor.is_quantized:
        kind = f"quantized {str(tensor.dtype).removeprefix('torch.')}"
    elif tensor.dtype == torch.float32 or str(tensor.dtype).removeprefix("torch.") in (
        CAST_TO_FLOAT32
    ):
        return
    else:
        kind = str(tensor.dtype).removeprefix("torch.")
    raise PolicyError(
        f"{path}: 'policy.pth' tensor {key!r} is {kind}; bbbench reads float32 weights "
        f"(float16, bfloat16 and float64 are cast to float32)"
    )
