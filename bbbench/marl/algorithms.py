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

With `normalize_advantage` (the default), the playing rows' advantages are scaled to
mean 0 and standard deviation 1 over the batch before the others are set to 0, as
MAPPO's reference code does over its active agents and stable-baselines3's PPO does
(BenchMARL's losses normalize none; the task pays at most 0.1 a step).

    from bbbench.marl.algorithms import MaskedMappoConfig
    MaskedMappoConfig.get_from_yaml()  # MAPPO's own defaults
"""

from __future__ import annotations

import dataclasses

import torch
from benchmarl.algorithms import IppoConfig, MappoConfig
from benchmarl.algorithms.ippo import Ippo
from benchmarl.algorithms.mappo import Mappo
from tensordict import TensorDictBase


def mask_advantage(group: str, batch: TensorDictBase, normalize: bool) -> TensorDictBase:
    """`batch` with the advantage of the rows whose bot is not playing set to 0; with
    `normalize`, the others' scaled to mean 0 and standard deviation 1 over the batch
    first (as MAPPO's own code does, over its active agents' rows)."""
    advantage = batch.get((group, "advantage"))
    if (group, "mask") in batch.keys(True, True):
        playing = batch.get((group, "mask")).unsqueeze(-1)
    else:
        playing = torch.ones_like(advantage, dtype=torch.bool)
    if normalize and playing.sum() > 1:
        active = advantage[playing]
        advantage = (advantage - active.mean()) / (active.std() + 1e-8)
    batch.set((group, "advantage"), advantage * playing)
    return batch


class MaskedAdvantage:
    """Mixed in before BenchMARL's IPPO or MAPPO: its advantages masked (and, with
    `normalize_advantage`, normalized over the playing rows) after its own GAE."""

    def __init__(self, normalize_advantage: bool, **kwargs):
        super().__init__(**kwargs)
        self.normalize_advantage = normalize_advantage

    def process_batch(self, group: str, batch: TensorDictBase) -> TensorDictBase:
        batch = super().process_batch(group, batch)
        return mask_advantage(group, batch, self.normalize_advantage)


class MaskedIppo(MaskedAdvantage, Ippo):
    pass


class MaskedMappo(MaskedAdvantage, Mappo):
    pass


@dataclasses.dataclass
class MaskedIppoConfig(IppoConfig):
    """IPPO (BenchMARL's config and defaults), fallen bots masked out of the objective;
    `normalize_advantage`: the playing rows' advantages normalized over each batch."""

    normalize_advantage: bool = True

    @staticmethod
    def associated_class():
        return MaskedIppo

    @classmethod
    def get_from_yaml(cls, path: str | None = None):
        return cls(**dataclasses.asdict(IppoConfig.get_from_yaml(path)))


@dataclasses.dataclass
class MaskedMappoConfig(MappoConfig):
    """MAPPO (BenchMARL's config and defaults), fallen bots masked out of the objective;
    `normalize_advantage`: the playing rows' advantages normalized over each batch."""

    normalize_advantage: bool = True

    @staticmethod
    def associated_class():
        return MaskedMappo

    @classmethod
    def get_from_yaml(cls, path: str | None = None):
        return cls(**dataclasses.asdict(MappoConfig.get_from_yaml(path)))
