"""Each single-bot task's own class, generated from its row of the suite.

A task is a row of `bbbench.tasks.suite`, not a class: `entry_point` is what
gymnasium registers for every single-bot task, and it plays the row with a subclass
of `BalanceEnv` named after the task (`BumpsEnv` for `bbbench/Bumps-v2`), made once
from the row of the task's newest version. Its docstring is that row's summary and
description with the task's Version History, so `help(env.unwrapped)` (and
`help(bbbench.envs.task_envs.BumpsEnv)`) says what the task adds to what `BalanceEnv`
documents for all of them. Made without a task, the class plays its newest version.
"""

from __future__ import annotations

import functools
import textwrap
from typing import Any

from bbbench.envs.balance import BalanceEnv
from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import SUITE, spec


class TaskEnv(BalanceEnv):
    """A `BalanceEnv` that plays its task's newest version unless told another."""

    default_task: str

    def __init__(self, task: str | TaskSpec | None = None, **kwargs: Any) -> None:
        super().__init__(task=self.default_task if task is None else task, **kwargs)


@functools.cache
def task_class(name: str) -> type[TaskEnv]:
    """The class of the single-bot task called `name` ("Bumps"), made from its newest row."""
    versions = [task for task in SUITE.values() if task.name == name and not task.multi_agent]
    if not versions:
        raise LookupError(f"no single-bot task of the suite is called {name!r}")
    newest = max(versions, key=lambda task: task.version)
    history = "\n".join(f"- {entry}" for entry in newest.version_history)
    earlier = "\n".join(
        f"- `{task.id}`: {task.summary}."
        + (f" {task.description.strip()}" if task.description != newest.description else "")
        for task in sorted(versions, key=lambda task: -task.version)[1:]
    )
    shared = newest.robot_model.task_interface()
    doc = (
        f"`{newest.id}`: {newest.summary}.\n\n{newest.description.strip()}\n\n"
        f"{shared}\n\n"
        + (f"## Earlier Versions (still registered)\n\n{earlier}\n\n" if earlier else "")
        + f"## Version History\n\n{history}\n"
    )
    return type(
        f"{name}Env",
        (TaskEnv,),
        {
            "__doc__": textwrap.indent(doc, "    ").lstrip(),
            "__module__": __name__,
            "default_task": newest.id,
        },
    )


def entry_point(task: str, **kwargs: Any) -> TaskEnv:
    """The env of a single-bot task: the entry point gymnasium registers for each."""
    return task_class(spec(task).name)(task=task, **kwargs)


entry_point.metadata = BalanceEnv.metadata  # what gymnasium.make reads of an entry point's modes


def __getattr__(attribute: str) -> type[TaskEnv]:
    """`bbbench.envs.task_envs.BumpsEnv` and the like: each task's class, by name (and so a
    pickled env finds its class)."""
    if attribute.endswith("Env"):
        try:
            return task_class(attribute.removesuffix("Env"))
        except LookupError:
            pass
    raise AttributeError(f"module {__name__!r} has no attribute {attribute!r}")
