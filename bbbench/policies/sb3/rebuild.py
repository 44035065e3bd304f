"""A zip's network rebuilt as stable-baselines3's own torch module, weights loaded strictly.

The network is built from the task's own spaces, the policy class the zip names
(one of `bbbench.policies.sb3.algorithms`' allowlisted classes) and the architecture read
as plain data; `load_state_dict(strict=True)` then refuses any weight that does not
fit it. Nothing of the zip is unpickled.
"""

from __future__ import annotations

from typing import Any

from gymnasium import spaces

from bbbench.policies.errors import PolicyError
from bbbench.policies.sb3.algorithms import ACTOR_CRITIC, load_class


def torch_policy(model, observation_space: spaces.Box, action_space: spaces.Space):
    """stable-baselines3's own policy module of `model` (an `SB3Zip`) for these spaces,
    weights loaded strictly."""
    import torch  # lazy: torch, for policy files only

    algorithm = model.algorithm
    kwargs = dict(model.architecture)
    if model.net_arch is not None:
        kwargs["net_arch"] = model.net_arch
    if model.activation is not None:
        kwargs["activation_fn"] = getattr(torch.nn, model.activation)
    if algorithm.family.trains_an_optimizer:
        # An optimizer is for training; building torch's Adam costs over a second.
        kwargs["optimizer_class"] = _NoOptimizer
        kwargs["lr_schedule"] = _no_learning
    else:
        kwargs.pop("use_sde", None)
    if algorithm.family is ACTOR_CRITIC and model.use_sde:
        kwargs["use_sde"] = True  # the algorithm, not policy_kwargs, passes it
    try:
        policy = load_class(model.policy_class)(observation_space, action_space, **kwargs)
    except (TypeError, ValueError, AssertionError) as error:
        raise PolicyError(
            f"{model.name}: cannot build its {algorithm.name} network: {error}"
        ) from None
    state = {key: torch.from_numpy(value) for key, value in model.weights.items()}
    try:
        policy.load_state_dict(state, strict=True)
    except RuntimeError as error:
        detail = " ".join(str(error).split())
        raise PolicyError(
            f"{model.name}: its weights do not fit a {algorithm.name} MLP with "
            f"net_arch={model.net_arch or 'default'} for {observation_space} -> "
            f"{action_space}: {detail[:300]}"
        ) from None
    policy.set_training_mode(False)
    return policy


class _NoOptimizer:
    """Stands in for the optimizer stable-baselines3 builds with every policy."""

    def __init__(self, parameters, lr: float = 0.0, **kwargs: Any) -> None:
        pass


def _no_learning(_progress: float) -> float:
    return 0.0
