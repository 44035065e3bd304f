"""The suite: task specs, the shared reward, observation layout and action table, the envs."""

from bbbench.tasks.factory import make, make_parallel
from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import SUITE, list_tasks, register_suite, spec

__all__ = [
    "SUITE",
    "TaskSpec",
    "list_tasks",
    "make",
    "make_parallel",
    "register_suite",
    "spec",
]
