"""IPPO and MAPPO whose fallen bots do not train the policy.

A bot that falls leaves the episode; TorchRL's `PettingZooWrapper` keeps its slot in
the batch (observation zeros, reward 0, terminated) until the team's episode ends,
and says so in `(group, "mask")`: False from the step after the fall. BenchMARL's
IPPO and MAPPO read no mask, so those rows would enter the PPO objective with an
advantage of -V(zeros), as if the bot had played. Here the advantage of every row
whose bot is not playing is set to 0 after BenchMARL computes it (GAE), so its
share of the objective, ratio x 0, and its policy gradient are 0 (with BenchMARL's
default `entropy_coef` of 0, nothing else of the row reaches the policy). The step
in which a bot falls is a real transition, and keeps its advantage.

    from bbbench.marl.algorithms import MaskedMappoConfig
    MaskedMappoConfig.get_from_yaml()  # MAPPO's own defaults
"""

from __future__ import annotations

import dataclasses

from benchmarl.algorithms import IppoConfig, MappoConfig
from benchmarl.algorithms.ippo import Ippo
from benchmarl.algorithms.mappo import Mappo
from tensordict import TensorDictBase


def mask_advantage(group: str, batch: TensorDictBase) -> TensorDictBase:
    """`batch` with the advantage of the rows whose bot is not playing set to 0."""
    if (group, "mask") in batch.keys(True, True):
        playing = batch.get((group, "mask")).unsqueeze(-1)
        advantage = batch.get((group, "advantage"))
        batch.set((group, "advantage"), advantage * playing)
    return batch


class MaskedIppo(Ippo):
    def process_batch(self, group: str, batch: TensorDictBase) -> TensorDictBase:
        return mask_advantage(group, super().process_batch(group, batch))


class MaskedMappo(Mappo):
    def process_batch(self, group: str, batch: TensorDictBase) -> TensorDictBase:
        return mask_advantage(group, super().process_batch(group, batch))


@dataclasses.dataclass
class MaskedIppoConfig(IppoConfig):
    """IPPO (BenchMARL's config and defaults), fallen bots masked out of the objective."""

    @staticmethod
    def associated_class():
        return MaskedIppo

    @classmethod
    def get_from_yaml(cls, path: str | None = None):
        return cls(**dataclasses.asdict(IppoConfig.get_from_yaml(path)))


@dataclasses.dataclass
class MaskedMappoConfig(MappoConfig):
    """MAPPO (BenchMARL's config and defaults), fallen bots masked out of the objective."""

    @staticmethod
    def associated_class():
        return MaskedMappo

    @classmethod
    def get_from_yaml(cls, path: str | None = None):
        return cls(**dataclasses.asdict(MappoConfig.get_from_yaml(path)))
