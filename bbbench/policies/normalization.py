"""The observation normalization a policy was trained with (stable-baselines3's
`VecNormalize` statistics, read by `bbbench.policies.sb3.vecnormalize`): what a policy
applies to each observation before its network, and what an ONNX export bakes in."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np


@dataclasses.dataclass(frozen=True, eq=False)
class ObservationNormalization:
    """`VecNormalize`'s observation statistics, and the file they came from."""

    file: str
    sha256: str
    normalize: bool  # VecNormalize's norm_obs: False leaves observations as they are
    mean: np.ndarray  # float64, the observation shape
    std: np.ndarray  # sqrt(var + epsilon), float64
    clip: float

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        """Observations as the policy saw them in training (float32)."""
        if not self.normalize:
            return observations
        scaled = (observations - self.mean) / self.std
        return np.clip(scaled, -self.clip, self.clip).astype(np.float32)

    def record(self) -> dict[str, Any]:
        """As the results document records it."""
        return {"file": self.file, "sha256": self.sha256, "normalize": self.normalize}
