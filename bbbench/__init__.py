"""bbbench: a benchmark suite for two-wheeled balancing robots.

    import gymnasium as gym
    import bbbench

    env = gym.make("bbbench/FlatBalance-v1")
    parallel_env = bbbench.make_parallel("bbbench/MultiBalance-v1", n_bots=8)
    batched_env = bbbench.make_batched("bbbench/MultiBalance-v1", worlds=16)  # (16, 4, ...)
    vec_env = bbbench.make_vec("bbbench/MultiBalance-v1", n_envs=2)  # for stable-baselines3
    bbbench.spec("bbbench/FlatBalance-v1").eval_seeds

Importing bbbench registers every task of the suite with gymnasium.
"""

import bbbench.sim  # noqa: F401  (first: it imports pybullet without its banner)
from bbbench.envs import make, make_batched, make_parallel
from bbbench.tasks import TaskSpec, list_tasks, register_suite, spec

__version__ = "0.1.0"
__all__ = [
    "TaskSpec",
    "__version__",
    "list_tasks",
    "make",
    "make_batched",
    "make_parallel",
    "make_vec",
    "spec",
]

register_suite()


def __getattr__(name: str):
    # make_vec imports stable-baselines3 (and torch): only when it is asked for.
    if name == "make_vec":
        from bbbench.vec import make_vec  # lazy: stable_baselines3, torch

        return make_vec
    raise AttributeError(f"module 'bbbench' has no attribute {name!r}")
