"""The acting network of a rebuilt stable-baselines3 policy, copied out to numpy.

Given the network rebuilt with its weights loaded strictly (`bbbench.policies.sb3.rebuild`),
the function of its family reads the layers that act, as the keywords of an `MlpActor`
(which runs them with portable arithmetic, `bbbench.portable`). Each algorithm family
lays its acting network out differently; `bbbench.policies.sb3.algorithms` names the
function below that reads each family's.
"""

from __future__ import annotations

from typing import Any

import numpy as np

Layer = tuple[np.ndarray, np.ndarray]


def actor_critic(policy, model, box: bool) -> dict[str, Any]:
    """PPO, A2C, TRPO: the policy branch of the MLP extractor, then the action net."""
    squash = bool(model.architecture.get("squash_output", False))
    layout = {
        "hidden": tuple(_linears(policy.mlp_extractor.policy_net)),
        "head": _linear(policy.action_net),
        "output": "argmax" if not box else "tanh" if squash else "gaussian",
    }
    if box and not model.use_sde:
        layout["log_std"] = policy.log_std.detach().numpy().copy()
    return layout


def q_network(policy, model, box: bool) -> dict[str, Any]:
    """DQN, QR-DQN: the online network (QR-DQN's head gives n_quantiles values per
    action), epsilon-greedy when acting stochastically."""
    if hasattr(policy, "quantile_net"):
        *hidden, head = _linears(policy.quantile_net.quantile_net)
        quantiles = policy.n_quantiles
    else:
        *hidden, head = _linears(policy.q_net.q_net)
        quantiles = 1
    return {
        "hidden": tuple(hidden),
        "head": head,
        "output": "argmax",
        "epsilon": model.exploration_rate,
        "quantiles": quantiles,
    }


def sac(policy, model, box: bool) -> dict[str, Any]:
    """SAC, TQC: the actor's latent layers, its mean, and its log std (or, under gSDE, the
    clip of its mean)."""
    [head] = _linears(policy.actor.mu)
    layout = {
        "hidden": tuple(_linears(policy.actor.latent_pi)),
        "head": head,
        "output": "squashed_gaussian",
    }
    if model.use_sde:
        layout["mean_clip"] = _hardtanh_bound(policy.actor.mu)
    else:
        layout["log_std"] = _linear(policy.actor.log_std)
    return layout


def td3(policy, model, box: bool) -> dict[str, Any]:
    """TD3: the actor, whose last layer is followed by tanh."""
    *hidden, head = _linears(policy.actor.mu)
    return {"hidden": tuple(hidden), "head": head, "output": "tanh"}


def ars(policy, model, box: bool) -> dict[str, Any]:
    """ARS: tanh-squashed, clipped, or the argmax of its logits."""
    *hidden, head = _linears(policy.action_net)
    output = "argmax" if not box else "tanh" if policy.squash_output else "clip"
    return {"hidden": tuple(hidden), "head": head, "output": output}


def _linear(layer) -> Layer:
    weight_t = np.ascontiguousarray(layer.weight.detach().numpy().T)
    if layer.bias is None:  # ARS's linear policy
        return weight_t, np.zeros(weight_t.shape[1], dtype=np.float32)
    return weight_t, layer.bias.detach().numpy().copy()


def _linears(sequential) -> list[Layer]:
    import torch  # lazy: torch, for policy files only

    if isinstance(sequential, torch.nn.Linear):
        return [_linear(sequential)]
    return [_linear(layer) for layer in sequential if isinstance(layer, torch.nn.Linear)]


def _hardtanh_bound(module) -> float | None:
    """SAC's and TQC's clip of their mean under gSDE (a Hardtanh after `mu`), if any."""
    import torch  # lazy: torch, for policy files only

    for layer in module.modules():
        if isinstance(layer, torch.nn.Hardtanh):
            return float(layer.max_val)
    return None
