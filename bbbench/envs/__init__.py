"""The environments: a task's episode (`Scene`) under the Gymnasium API (`BalanceEnv`, and
a class per single-bot task in `bbbench.envs.tasks`) and the PettingZoo API
(`MultiBalanceEnv`); `make` and `make_parallel` build them by task ID."""

from bbbench.envs.balance import BalanceEnv
from bbbench.envs.factory import make, make_parallel
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.envs.scene import EpisodeDraw, Scene

__all__ = ["BalanceEnv", "EpisodeDraw", "MultiBalanceEnv", "Scene", "make", "make_parallel"]
