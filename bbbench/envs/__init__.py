"""The environments: a task's episode (`Scene`) under the Gymnasium API (`BalanceEnv`, and
a class per single-bot task in `bbbench.envs.task_envs`) and the PettingZoo API
(`MultiBalanceEnv`), and many worlds of it as arrays (`BatchedEnv`); `make`,
`make_parallel` and `make_batched` build them by task ID."""

from bbbench.envs.balance import BalanceEnv
from bbbench.envs.batched import BatchedEnv
from bbbench.envs.episode import EpisodeDraw
from bbbench.envs.factory import make, make_batched, make_parallel
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.envs.scene import Scene

__all__ = [
    "BalanceEnv",
    "BatchedEnv",
    "EpisodeDraw",
    "MultiBalanceEnv",
    "Scene",
    "make",
    "make_batched",
    "make_parallel",
]
