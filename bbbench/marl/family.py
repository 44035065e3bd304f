"""bbbench's multi-bot and team tasks as a BenchMARL task family.

One BenchMARL task per latest multi-bot task ID (`BbbenchTask`). BenchMARL asks a task
for an env of `num_envs` worlds; a bbbench task gives one batched env of that many
worlds (`bbbench.marl.batched_env`, `batch_size=[num_envs]`, as VMAS's), so the
collector calls the policy once a step for every world, and every bot is in one
group, `bot`; a mixed team's bots are in a group per robot
(`bbbench.envs.worlds.agent_groups`), each in its own spaces, one policy each. The
task's configuration, made from its row (`task_config`), holds the env's own keywords
(`n_bots`) and `workers`, the processes that step the worlds (the same results for any
number). The action mode
follows BenchMARL's `prefer_continuous_actions`: `Discrete(9)` or `Box(-1, 1, (1,))`
per bot.

A bot that falls leaves the episode (the others play on, on the crossing tasks); the
env reports which bots are still playing as `("bot", "mask")`, with the keys and
values of TorchRL's `PettingZooWrapper` over the task's parallel env
(tests/test_batched.py).
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import torch
from benchmarl.environments import task_config_registry
from benchmarl.environments.common import Task, TaskClass
from benchmarl.utils import _read_yaml_config
from torchrl.data import Composite
from torchrl.envs import EnvBase, ObservationNorm, Transform

import bbbench
from bbbench.marl.batched import batched_env

ENV_NAME = "bbbench"


def member_name(task_id: str) -> str:
    """The BenchMARL task name of a bbbench task ID: bbbench/MultiBalance-v1 -> MULTIBALANCE_V1."""
    return task_id.removeprefix("bbbench/").replace("-", "_").upper()


def task_config(task_id: str) -> dict[str, Any]:
    """A task's BenchMARL configuration, from its row of the suite: the env's own
    keywords at their defaults (`n_bots`, and a channel's `message_width`, `comm_range`
    and `mute_messages`) and `workers`, the processes that step the worlds (1; the same
    results for any number). BenchMARL's hydra CLI finds the same in hydra's config store
    (`bbbench.marl.run`)."""
    task = bbbench.spec(task_id)
    if task.group is None:
        raise ValueError(f"{task_id} is a single-bot task: BenchMARL trains the multi-bot ones")
    config: dict[str, Any] = {"n_bots": task.group.n_bots}
    if task.channel is not None:
        channel = task.channel
        config.update(
            message_width=channel.width, comm_range=channel.range, mute_messages=channel.muted
        )
    return {**config, "workers": 1}


def task_class(task_id: str, **changes: Any) -> BbbenchTaskClass:
    """The BenchMARL task of any multi-bot task of the suite (no member of `BbbenchTask`
    needed), its configuration from the suite with `changes`."""
    config = {**task_config(task_id), **changes}
    return BbbenchTaskClass(name=member_name(task_id), config=config)


def task_id(name: str) -> str:
    """The bbbench task ID of a BenchMARL task name: MULTIBALANCE_V1 -> bbbench/MultiBalance-v1."""
    wanted = name.lower().replace("_v", "-v")
    for candidate in bbbench.list_tasks():
        if candidate.removeprefix("bbbench/").lower() == wanted:
            return candidate
    raise ValueError(f"no bbbench task for BenchMARL's {name!r}")


class BbbenchTaskClass(TaskClass):
    """A bbbench multi-bot task, as BenchMARL builds and reads it.

    `observation_normalization`, if set to (mean, std) per observation value for each
    agent group (`bbbench.envs.worlds.agent_groups`), puts a fixed `ObservationNorm` per
    group in front of the models ((observation - mean) / std), in training and evaluation
    alike: what `bbbench train` sets from its classical controller's play
    (`bbbench.training.benchmarl`).
    """

    observation_normalization: dict[str, tuple[Any, Any]] | None = None

    @property
    def task_id(self) -> str:
        return task_id(self.name)

    @property
    def env_kwargs(self) -> dict[str, Any]:
        """The env's keywords in the configuration (all but `workers`)."""
        return {key: value for key, value in self.config.items() if key != "workers"}

    def get_env_fun(
        self, num_envs: int, continuous_actions: bool, seed: int | None, device: Any
    ) -> Callable[[], EnvBase]:
        config = copy.deepcopy(self.env_kwargs)
        workers = min(int(self.config.get("workers", 1)), num_envs)
        mode = "continuous" if continuous_actions else "discrete"
        task = self.task_id

        def make() -> EnvBase:
            env = batched_env(
                task, worlds=num_envs, workers=workers, device=device, action_mode=mode, **config
            )
            env.set_seed(seed)
            return env

        return make

    def supports_continuous_actions(self) -> bool:
        return True

    def supports_discrete_actions(self) -> bool:
        return "discrete" in bbbench.spec(self.task_id).action_modes

    def get_env_transforms(self, env: EnvBase) -> list[Transform]:
        if self.observation_normalization is None:
            return []
        return [
            ObservationNorm(
                loc=torch.as_tensor(mean, dtype=torch.float32),
                scale=torch.as_tensor(std, dtype=torch.float32),
                in_keys=[(group, "observation")],
                standard_normal=True,
            )
            for group, (mean, std) in self.observation_normalization.items()
        ]

    def max_steps(self, env: EnvBase) -> int:
        return bbbench.spec(self.task_id).max_episode_steps

    def has_render(self, env: EnvBase) -> bool:
        return False  # a batch of worlds renders no frame: bbbench eval --video does

    def group_map(self, env: EnvBase) -> dict[str, list[str]]:
        return env.group_map

    def _keys(self, env: EnvBase, keep: str) -> Composite | None:
        spec = env.full_observation_spec_unbatched.clone()  # one world's, as VMAS's family
        for group in self.group_map(env):
            for key in list(spec[group].keys()):
                if key != keep:
                    del spec[group][key]
            if spec[group].is_empty():
                del spec[group]
        return None if spec.is_empty() else spec

    def observation_spec(self, env: EnvBase) -> Composite:
        return self._keys(env, "observation")

    def info_spec(self, env: EnvBase) -> Composite | None:
        return self._keys(env, "info")

    def state_spec(self, env: EnvBase) -> Composite | None:
        return None

    def action_mask_spec(self, env: EnvBase) -> Composite | None:
        return None

    def action_spec(self, env: EnvBase) -> Composite:
        return env.full_action_spec_unbatched

    @staticmethod
    def env_name() -> str:
        return ENV_NAME


class _Family(Task):
    """What every member of `BbbenchTask` does (an Enum with members cannot be
    subclassed: the members are made below, from the suite)."""

    @staticmethod
    def associated_class():
        return BbbenchTaskClass

    def get_from_yaml(self, path: str | None = None) -> TaskClass:
        """The task with its configuration from its row of the suite (`task_config`), or
        from the YAML file at `path`."""
        if path is None:
            return self.get_task(config=task_config(task_id(self.name)))
        return self.get_task(config=_read_yaml_config(str(path)))


# bbbench's latest multi-bot and team tasks, for BenchMARL: one member each, from the suite.
BbbenchTask = _Family(
    "BbbenchTask",
    [(member_name(t), None) for t in bbbench.list_tasks(multi_agent=True, latest=True)],
    module=__name__,
)

for _task in BbbenchTask:
    task_config_registry[f"{ENV_NAME}/{_task.name.lower()}"] = _task
