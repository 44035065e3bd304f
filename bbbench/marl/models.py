"""The neighbour encoder as a BenchMARL model, for a decentralised actor (or critic).

`NeighbourEncoderConfig.for_task(task_id)` lays it over the task's observation as its
scenario says (`Scenario.slots`): on the team tasks, 9 own values and 2 slots of 5 (the
bot ahead, the bot behind), each slot's presence bit first, mean-pooled over the
present ones; on the crossing tasks (MultiBalance, MultiBumps), 5 own values and 3
slots of 4, with no presence bit (an empty slot is zeros); on a mixed team, each robot
group's own layout (`Scenario.bot_slots`). Every bot of a group shares its parameters.
The network is `bbbench.policies.encoder.neighbour_encoder`, which
`export_onnx` writes for the board (`model.net`).

`RecurrentActor` is BenchMARL's own GRU model (`benchmarl.models.Gru`: one GRU cell over
the observation, then an MLP) as one torch network that steps once: (observation,
state) -> (action scores, next state), which `onnx_bytes(state_width=...)` writes as the
recurrent contract the board plays.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import MISSING

import torch
from benchmarl.models import Gru
from benchmarl.models.common import Model, ModelConfig
from tensordict import TensorDictBase

import bbbench
from bbbench.envs.worlds import group_slots
from bbbench.policies.encoder import neighbour_encoder


class NeighbourEncoderModel(Model):
    """`neighbour_encoder` on every bot's observation, one set of parameters for all."""

    def __init__(self, own, slots, slot_width, presence, embed, hidden, pool, groups, **kwargs):
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
        if groups is not None:  # a mixed team: this group's robot lays its observation out
            own, slots, slot_width, presence = groups[self.agent_group]
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
    # On a mixed team, each agent group's (own, slots, slot_width, presence), by group.
    groups: dict[str, tuple[int, int, int, int | None]] | None = None

    @staticmethod
    def associated_class():
        return NeighbourEncoderModel

    @classmethod
    def for_task(cls, task_id: str, **changes) -> NeighbourEncoderConfig:
        """The encoder laid over `task_id`'s observation (`changes`: embed, hidden, pool)."""
        task = bbbench.spec(task_id)
        if not task.multi_agent:
            raise ValueError(f"{task_id} is a single-bot task: it has no neighbours to encode")
        table = group_slots(task)  # one scenario built; the first group's is the task's
        if any(layout is None for layout in table.values()):
            raise ValueError(f"{task_id}'s rows have no neighbour slots to encode")
        own, slots, slot_width, presence = next(iter(table.values()))
        groups = None
        if task.mixed:
            groups = {group: tuple(layout) for group, layout in table.items()}
        return cls(
            own=own, slots=slots, slot_width=slot_width, presence=presence, groups=groups, **changes
        )


class RecurrentActor(torch.nn.Module):
    """A trained `Gru` model (shared by every bot) as one step of `torch.nn.GRU` and its
    MLP: `forward(obs, state)` gives `(scores, next_state)`, each state (bots,
    `state_width`), as BenchMARL's collection steps it (zeros at an episode's start).
    torch writes `torch.nn.GRU` as ONNX's GRU operator, which bbbench's interpreter runs
    on its portable arithmetic."""

    def __init__(self, model: Gru) -> None:
        super().__init__()
        gru = model.gru
        if model.n_layers != 1 or not model.share_params or model.centralised:
            raise ValueError(
                "the board's recurrent contract carries one GRU layer shared by every bot "
                f"(got n_layers={model.n_layers}, share_params={model.share_params}, "
                f"centralised={model.centralised})"
            )
        cell = gru.params["grus", "0"]
        self.state_width = gru.hidden_size
        self.gru = torch.nn.GRU(gru.input_size, gru.hidden_size)
        with torch.no_grad():
            for name in ("weight_ih", "weight_hh", "bias_ih", "bias_hh"):
                target = getattr(self.gru, f"{name}_l0")
                source = cell.get(name, None)  # BenchMARL's bias=False: no biases
                target.copy_(torch.zeros_like(target) if source is None else source)
        self.mlp = model.mlp.get_stateful_net()

    def forward(self, obs: torch.Tensor, state: torch.Tensor):
        out, next_state = self.gru(obs.unsqueeze(0), state.unsqueeze(0))
        return self.mlp(out[0]), next_state[0]


class DeterministicAction(torch.nn.Module):
    """A continuous BenchMARL actor's deterministic action: the first `actions` values of
    its network's output (the loc, as `NormalParamExtractor` splits loc from scale),
    through tanh, which is `TanhNormal`'s deterministic sample on [-1, 1] (BenchMARL's
    `use_tanh_normal`, its PPO default)."""

    def __init__(self, net: torch.nn.Module, actions: int) -> None:
        super().__init__()
        self.net, self.actions = net, actions

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return torch.tanh(self.net(obs)[..., : self.actions])
