"""A stable-baselines3 `.zip` as a `Policy`: read safely, acting in numpy or torch."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from gymnasium import spaces

from bbbench.policies.errors import PolicyError
from bbbench.policies.file_policy import FilePolicy
from bbbench.policies.mlp import MlpActor
from bbbench.policies.normalization import ObservationNormalization
from bbbench.policies.policy import Actor, NormalizedActor, TorchActor, describe_space
from bbbench.policies.sb3.reader import SB3Zip, read_sb3_zip
from bbbench.policies.sb3.rebuild import torch_policy
from bbbench.tasks.suite import agent_spaces


class SB3ZipPolicy(FilePolicy):
    """A stable-baselines3 `.zip`, read without unpickling (`bbbench.policies.sb3.reader`).

    Its actor runs the network in numpy (`backend="numpy"`, the default: faster
    for small MLPs) or as stable-baselines3's own torch module (`"torch"`).
    `normalization`: the `VecNormalize` statistics the policy was trained with
    (`bbbench.policies.sb3.vecnormalize`), applied to every observation first.
    """

    deterministic_only = None  # its action distribution, sampled with `--stochastic`

    def __init__(
        self,
        path: str | Path,
        backend: str = "numpy",
        normalization: ObservationNormalization | None = None,
    ) -> None:
        if backend not in ("numpy", "torch"):
            raise ValueError(f"backend must be 'numpy' or 'torch', got {backend!r}")
        self.loaded = loaded = read_sb3_zip(path)
        self.name = loaded.name
        self.sha256 = loaded.sha256
        self.algorithm = loaded.algorithm.name
        self.action_mode = loaded.action_mode
        self.backend = backend
        self.normalization = normalization
        self.observation_shape = loaded.observation_shape
        self.action_space = loaded.action_space
        self._set_layout()
        self._actors: dict[tuple, Actor] = {}

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        if not deterministic and self.loaded.use_sde:
            raise PolicyError(
                f"{self.name}: trained with gSDE (use_sde=True), whose exploration noise is "
                f"not saved in the zip: bbbench evaluates it deterministically only (drop "
                f"--stochastic)"
            )
        observation_space, action_space = agent_spaces(task_id, self.action_mode, self.height_scan)
        key = (observation_space.shape, describe_space(action_space), self.backend)
        if key not in self._actors:
            if self.backend == "numpy":
                actor = numpy_actor(self.loaded, observation_space, action_space)
            else:
                actor = TorchActor(torch_policy(self.loaded, observation_space, action_space))
            if self.normalization is not None:
                actor = NormalizedActor(actor, self.normalization)
            self._actors[key] = actor
        return self._actors[key]

    def record(self) -> dict[str, Any]:
        record = super().record()
        if self.normalization is not None:
            record["observation_normalization"] = self.normalization.record()
        return record


def numpy_actor(model: SB3Zip, observation_space: spaces.Box, action_space: spaces.Space):
    """The acting network of `model` in numpy, read from the strictly loaded torch module."""
    policy = torch_policy(model, observation_space, action_space)
    box = isinstance(action_space, spaces.Box)
    layout = model.algorithm.family.extract(policy, model, box)
    return MlpActor(
        activation=model.activation or model.algorithm.activation,
        low=action_space.low.copy() if box else None,
        high=action_space.high.copy() if box else None,
        **layout,
    )
