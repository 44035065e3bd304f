"""The suite as data: task specs, the table of IDs, and the components every task shares
(reward, observation layout, action table, sensors, commands, groups). The envs that play
them are in `bbbench.envs`."""

from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import SUITE, list_tasks, register_suite, spec

__all__ = ["SUITE", "TaskSpec", "list_tasks", "register_suite", "spec"]
