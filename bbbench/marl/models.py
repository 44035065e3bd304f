"""The neighbour encoder as a BenchMARL model, for a decentralised actor (or critic).

`NeighbourEncoderConfig.for_task(task_id)` lays it over the task's observation as its
scenario says (`Scenario.slots`): on the team tasks, 9 own values and 2 slots of 5 (the
bot ahead, the bot behind), each slot's presence bit first, mean-pooled over the
present ones; on the crossing tasks (MultiBalance, MultiBumps), 5 own values and 3
slots of 4, with no presence bit (an empty slot is zeros). Every bot shares its
parameters. The network is `bbbench.policies.encoder.neighbour_encoder`, which
`export_onnx` writes for the board (`model.net`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import MISSING

from benchmarl.models.common import Model, ModelConfig
from tensordict import TensorDictBase

import bbbench
from bbbench.policies.encoder import neighbour_encoder


class NeighbourEncoderModel(Model):
    """`neighbour_encoder` on every bot's observation, one set of parameters for all."""

    def __init__(self, own, slots, slot_width, presence, embed, hidden, pool, **kwargs):
        super().__init__(
            input_spec=kwargs.pop("input_spec"),
            output_spec=kwargs.pop("output_spec"),
            agent_group=kwargs.pop("agent_group"),
            input_has_agent_dim=kwargs.pop("input_has_agent_dim"),
            n_agents=kwargs.pop("n_agents"),
            centralised=kwargs.pop("centralised"),
            share_params=kwargs.pop("share_params"),
            device=kwargs.pop("device"),
            action_spec=kwargs.pop("action_spec"),
            model_index=kwargs.pop("model_index"),
            is_critic=kwargs.pop("is_critic"),
        )
        self.output_features = self.output_leaf_spec.shape[-1]
        self.net = neighbour_encoder(
            own, slots, slot_width, self.output_features, presence, embed, tuple(hidden), pool
        ).to(self.device)

    def _perform_checks(self) -> None:
        super()._perform_checks()
        if self.centralised or not self.share_params or not self.input_has_agent_dim:
            raise ValueError(
                "the neighbour encoder reads each bot's own observation with parameters "
                "shared by every bot: a decentralised model with share_params=True"
            )
        if len(self.in_keys) != 1:
            raise ValueError(f"the neighbour encoder reads one observation, got {self.in_keys}")

    def _forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        observations = tensordict.get(self.in_keys[0])  # (..., bots, values)
        out = self.net(observations.reshape(-1, observations.shape[-1]))
        tensordict.set(self.out_key, out.reshape(*observations.shape[:-1], -1))
        return tensordict


@dataclasses.dataclass
class NeighbourEncoderConfig(ModelConfig):
    """BenchMARL's config of a `NeighbourEncoderModel`."""

    own: int = MISSING
    slots: int = MISSING
    slot_width: int = MISSING
    presence: int | None = None
    embed: int = 32
    hidden: Sequence[int] = (64, 64)
    pool: str = "mean"

    @staticmethod
    def associated_class():
        return NeighbourEncoderModel

    @classmethod
    def for_task(cls, task_id: str, **changes) -> NeighbourEncoderConfig:
        """The encoder laid over `task_id`'s observation (`changes`: embed, hidden, pool)."""
        task = bbbench.spec(task_id)
        if not task.multi_agent:
            raise ValueError(f"{task_id} is a single-bot task: it has no neighbours to encode")
        own, slots, slot_width, presence = task.scenario_class(task).slots()
        return cls(own=own, slots=slots, slot_width=slot_width, presence=presence, **changes)
