"""`bbbench train`: train a policy on a task with the recipe shipped for it.

    from bbbench.training import train
    result = train(["bbbench/FlatBalance-v1"], "ppo", out="policy.zip", seed=0)

The training loop is `bbbench.training.trainer`; its evaluation during training,
`bbbench.training.callbacks`; the rl-zoo3 recipe files, `bbbench.training.recipes`.
"""

from bbbench.training.logs import Trained
from bbbench.training.recipes import (
    MARL_TRAINABLE,
    MIX,
    TRAINABLE,
    Recipe,
    check_collection,
    check_policy_path,
    recipe,
)
from bbbench.training.seeds import EVALUATION_EPISODES, evaluation_seeds
from bbbench.training.trainer import (
    build_model,
    check_request,
    reproducible_zip,
    statistics_path,
    train,
    training_env,
)

__all__ = [
    "EVALUATION_EPISODES",
    "MARL_TRAINABLE",
    "MIX",
    "TRAINABLE",
    "Recipe",
    "Trained",
    "build_model",
    "check_collection",
    "check_policy_path",
    "check_request",
    "evaluation_seeds",
    "recipe",
    "reproducible_zip",
    "statistics_path",
    "train",
    "training_env",
]
