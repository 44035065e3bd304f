"""`TaskSpec`: everything that defines one versioned task, frozen."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field

from bbbench.robots import FALL_TILT, MODEL
from bbbench.tasks.commands import ConstantVelocity
from bbbench.tasks.reward import RewardWeights
from bbbench.terrain import FlatGround

# Fields that document a task without changing its behaviour: editing them
# must not change the fingerprint.
_DOCUMENTATION_FIELDS = ("summary",)


@dataclass(frozen=True)
class TaskSpec:
    """One task of the suite. A task is a row of specs, not a class.

    Changing any field but `summary` changes `fingerprint`, and so needs a new
    version of the task ID.
    """

    id: str
    summary: str
    terrain: FlatGround = field(default_factory=FlatGround)
    command: ConstantVelocity = field(default_factory=ConstantVelocity)
    reward: RewardWeights = field(default_factory=RewardWeights)
    initial_pitch: float = 0.1  # rad: reset leans the bot by U(-initial_pitch, initial_pitch)
    control_dt: float = 0.01  # s per env step
    physics_substeps: int = 1  # pybullet sub-steps per env step
    max_episode_steps: int = 1500  # time limit (truncation)
    eval_seeds: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if not self.id.startswith("bbbench/") or "-v" not in self.id:
            raise ValueError(f"task IDs look like 'bbbench/Name-vN', got {self.id!r}")
        if not 0.0 <= self.initial_pitch < FALL_TILT:
            raise ValueError(
                f"initial_pitch must be in [0, {FALL_TILT:.3f}) rad (the fall limit), "
                f"got {self.initial_pitch!r}"
            )
        if not self.control_dt > 0 or self.max_episode_steps < 1 or self.physics_substeps < 1:
            raise ValueError(
                f"{self.id}: control_dt > 0, max_episode_steps >= 1 and physics_substeps >= 1 "
                f"are required, got {self.control_dt!r}, {self.max_episode_steps!r}, "
                f"{self.physics_substeps!r}"
            )
        if len(set(self.eval_seeds)) != len(self.eval_seeds):
            raise ValueError(f"{self.id}: eval_seeds must not repeat")

    @property
    def max_return(self) -> float:
        """The best possible episode return: every step upright and on target."""
        return self.reward.upright * self.max_episode_steps

    @property
    def fingerprint(self) -> str:
        """A hash of everything that decides the task's behaviour, robot model included."""
        behaviour = {
            key: value
            for key, value in dataclasses.asdict(self).items()
            if key not in _DOCUMENTATION_FIELDS
        }
        # Class names tell apart components whose fields happen to match.
        behaviour["components"] = [
            type(self.terrain).__name__,
            type(self.command).__name__,
            type(self.reward).__name__,
        ]
        digest = hashlib.sha256(json.dumps(behaviour, sort_keys=True).encode())
        digest.update(MODEL.urdf_path.read_bytes())
        return digest.hexdigest()[:16]
