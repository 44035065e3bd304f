"""The suite as data: task specs, the table of IDs, and the components every task shares
(reward, observation layout, action table, sensors, commands, groups). The envs that play
them are in `bbbench.envs`."""

import importlib

from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import SUITE, list_tasks, register_suite, spec

__all__ = ["SUITE", "TaskSpec", "list_tasks", "register_suite", "spec"]

# Names this package had before the envs moved to `bbbench.envs`, still importable: the
# modules `bbbench.tasks.balance`, `.multi`, `.envs` (the same module objects as their new
# names), and `make`, `make_parallel`. Looked up on first use, so that the task data
# imports no env code.
_MOVED = {
    "balance": "bbbench.envs.balance",
    "multi": "bbbench.envs.multi",
    "envs": "bbbench.envs.tasks",
    "make": "bbbench.envs.factory",
    "make_parallel": "bbbench.envs.factory",
}


def __getattr__(name: str):
    if name not in _MOVED:
        raise AttributeError(f"module 'bbbench.tasks' has no attribute {name!r}")
    module = importlib.import_module(_MOVED[name])
    return getattr(module, name) if name.startswith("make") else module
