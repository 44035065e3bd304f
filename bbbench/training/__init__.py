"""`bbbench train`: train a policy on a task with the recipe shipped for it.

    from bbbench.training import train
    result = train(["bbbench/FlatBalance-v1"], "ppo", out="policy.zip", seed=0)

One table of algorithms (`bbbench.training.algorithms`) says which route trains each:
`bbbench.training.sb3` (stable-baselines3, rl-zoo3 recipes, a zip) or
`bbbench.training.benchmarl` (BenchMARL on multi-bot tasks, ONNX). What both share sits
here: the request and its checks (`trainer`, `checks`), the recipe files
(`recipe_files`), the training seeds (`seeds`), the logs (`logs`), the count of trainings
beside (`beside`) and the fan-out of seeds (`fanout`).
"""

from bbbench.training.algorithms import ALGORITHMS, MARL_TRAINABLE, TRAINABLE, trainable
from bbbench.training.checks import (
    StoppedTrainingError,
    check_collection,
    check_fresh,
    check_policy_path,
    policy_suffix,
)
from bbbench.training.logs import Trained
from bbbench.training.sb3.recipes import MIX, Recipe, statistics_path
from bbbench.training.seeds import EVALUATION_EPISODES, evaluation_seeds
from bbbench.training.trainer import check_request, recipe, train

__all__ = [
    "ALGORITHMS",
    "EVALUATION_EPISODES",
    "MARL_TRAINABLE",
    "MIX",
    "TRAINABLE",
    "Recipe",
    "StoppedTrainingError",
    "Trained",
    "check_collection",
    "check_fresh",
    "check_policy_path",
    "check_request",
    "evaluation_seeds",
    "policy_suffix",
    "recipe",
    "statistics_path",
    "train",
    "trainable",
]
