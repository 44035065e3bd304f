"""A permutation-invariant neighbour encoder for multi-bot observations, in torch.

A multi-bot observation is the bot's own values, then K slots of the same
width, one per neighbour (`bbbench.envs.multi`): the team tasks' 19 are 9 own
values and 2 slots of 5 (a presence bit, then where the bot ahead or behind is
and how it moves). The encoder applies one small layer to every slot (the same
weights for all), pools the slots (a mean over the present ones, or a max), and
feeds the bot's own values with the pooled ones to an MLP head:

    own, slots = obs[:, :own], obs[:, own:].reshape(-1, K, width)
    h = relu(slots @ W + b)                  # shared across the slots
    h = h * present                          # an absent neighbour adds nothing
    pooled = sum(h) / max(sum(present), 1)   # or max(h)
    out = head(concat(own, pooled))

Swapping two neighbours' slots changes nothing. It exports (`export_onnx`) to
the operators bbbench's interpreter runs (Slice, Reshape, MatMul, Add, Relu,
Mul, ReduceSum, ReduceMax, Clip, Div, Concat, Gemm, Tanh), with the same bits
on every CPU.
"""

from __future__ import annotations

from typing import Any


def neighbour_encoder(
    own: int,
    slots: int,
    slot_width: int,
    actions: int,
    presence: int | None = None,
    embed: int = 32,
    hidden: tuple[int, ...] = (64, 64),
    pool: str = "mean",
) -> Any:
    """A torch module: observations (k, own + slots x slot_width) -> (k, actions).

    `presence`: the index, within a slot, of its presence bit (1 for a neighbour, 0 for
    none); None: every slot counts. `pool`: "mean" over the present slots, or "max"
    (ReLU features are at least 0, so an absent slot's 0 never wins)."""
    import torch  # lazy: torch, for training and exporting only

    if pool not in ("mean", "max"):
        raise ValueError(f"pool must be 'mean' or 'max', got {pool!r}")
    if presence is not None and not 0 <= presence < slot_width:
        raise ValueError(f"presence {presence}: an index within a slot of {slot_width}")

    class NeighbourEncoder(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.per_slot = torch.nn.Linear(slot_width, embed)
            layers, width = [], own + embed
            for size in hidden:
                layers += [torch.nn.Linear(width, size), torch.nn.Tanh()]
                width = size
            self.head = torch.nn.Sequential(*layers, torch.nn.Linear(width, actions))

        def forward(self, obs):
            grouped = obs[:, own : own + slots * slot_width].reshape(-1, slots, slot_width)
            pooled = pool_slots(torch.relu(self.per_slot(grouped)), grouped, presence, pool)
            return self.head(torch.cat([obs[:, :own], pooled], dim=1))

    return NeighbourEncoder()


def pool_slots(h: Any, grouped: Any, presence: int | None, pool: str) -> Any:
    """The slots' features `h` (k, K, embed), of the slots `grouped` (k, K, width), pooled
    into (k, embed) as `neighbour_encoder` says: an absent slot's (its presence bit 0)
    zeroed, then "mean" over the present slots (every slot's, with no `presence`) or
    "max"."""
    if presence is not None:
        present = grouped[:, :, presence : presence + 1]
        h = h * present
    if pool == "max":
        return h.amax(dim=1)
    if presence is not None:
        return h.sum(dim=1) / present.sum(dim=1).clamp(min=1.0)
    return h.mean(dim=1)
