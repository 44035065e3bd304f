"""bbbench: a benchmark suite for two-wheeled balancing robots.

    import gymnasium as gym
    import bbbench

    env = gym.make("bbbench/FlatBalance-v0")
    bbbench.spec("bbbench/FlatBalance-v0").eval_seeds

Importing bbbench registers every task of the suite with gymnasium.
"""

from bbbench.tasks import TaskSpec, list_tasks, make, register_suite, spec

__version__ = "0.1.0"
__all__ = ["TaskSpec", "__version__", "list_tasks", "make", "spec"]

register_suite()
