"""bbbench's multi-bot and team tasks as a BenchMARL task family.

Every task is its PettingZoo parallel env (`bbbench.make_parallel`) in TorchRL's
`PettingZooWrapper`, whose group map puts every bot in one group, `bot`. One
BenchMARL task per latest multi-bot task ID (`BbbenchTask`); its configuration
(`conf/task/bbbench/<name>.yaml`) holds the env's own keywords: `n_bots`, and
`difficulty` on terrain. The action mode follows BenchMARL's
`prefer_continuous_actions`: `Discrete(9)` or `Box(-1, 1, (1,))` per bot.

A bot that falls leaves the episode (the others play on, on the crossing
tasks); the wrapper reports which bots are still playing as `("bot", "mask")`.

`BbbenchWrapper` is that wrapper with its step rewritten for bbbench's envs: the same
tensordict, bit for bit (tests/test_marl_benchmarl.py), in a third of the time.
TorchRL's own step looks the live bots up through `EnvBase.__getattr__` (which lists
the wrapper's attributes on every miss), deep-copies the observations to strip action
masks bbbench has none of, and writes every value as a tensor of its own.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch
from benchmarl.environments import task_config_registry
from benchmarl.environments.common import Task, TaskClass
from benchmarl.utils import _read_yaml_config
from tensordict import TensorDictBase
from torchrl.data import Composite
from torchrl.envs import EnvBase, ObservationNorm, Transform
from torchrl.envs.libs.pettingzoo import PettingZooWrapper

import bbbench

CONF = Path(__file__).with_name("conf") / "task"
ENV_NAME = "bbbench"


def task_id(name: str) -> str:
    """The bbbench task ID of a BenchMARL task name: MULTIBALANCE_V1 -> bbbench/MultiBalance-v1."""
    wanted = name.lower().replace("_v", "-v")
    for candidate in bbbench.list_tasks():
        if candidate.removeprefix("bbbench/").lower() == wanted:
            return candidate
    raise ValueError(f"no bbbench task for BenchMARL's {name!r}")


class BbbenchWrapper(PettingZooWrapper):
    """TorchRL's `PettingZooWrapper` over a bbbench parallel env (masked bots, done when
    every bot is), with a step that writes its tensordict through numpy views."""

    def _init_env(self) -> None:
        super()._init_env()
        if any(self.has_action_mask.values()) or self.return_state or not self.parallel:
            raise ValueError("BbbenchWrapper takes a parallel env with no action mask or state")
        if not self.use_mask or self.done_on_any:
            raise ValueError("BbbenchWrapper needs use_mask=True and done_on_any=False")

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        actions = {}
        for group, agents in self.group_map.items():
            chosen = tensordict.get((group, "action")).detach().cpu().numpy()
            actions.update(zip(agents, chosen, strict=True))
        observations, rewards, terminations, truncations, infos = self._env.step(actions)
        playing = set(self._env.agents)
        out = self.cached_step_output_zero.clone()
        done = terminated = truncated = True
        for group, agents in self.group_map.items():
            views = {key: out.get((group, key)).numpy() for key in _STEP_KEYS}
            info = out.get((group, "info"), None)
            info_views = {} if info is None else {key: value.numpy() for key, value in info.items()}
            for index, agent in enumerate(agents):
                views["mask"][index] = agent in playing
                ended = terminations.get(agent, True), truncations.get(agent, True)
                views["terminated"][index], views["truncated"][index] = ended
                views["done"][index] = ended[0] or ended[1]
                if agent not in observations:  # fallen before this step: zeros, as TorchRL
                    continue
                views["observation"][index] = observations[agent]
                views["reward"][index] = rewards[agent]
                for key, value in infos[agent].items():
                    info_views[key][index] = value
            done &= bool(views["done"].all())
            terminated &= bool(views["terminated"].all())
            truncated &= bool(views["truncated"].all())
        out.set("done", torch.tensor([done], device=self.device))
        out.set("terminated", torch.tensor([terminated], device=self.device))
        out.set("truncated", torch.tensor([truncated], device=self.device))
        return out


_STEP_KEYS = ("mask", "observation", "reward", "done", "terminated", "truncated")


class BbbenchTaskClass(TaskClass):
    """A bbbench multi-bot task, as BenchMARL builds and reads it.

    `observation_normalization`, if set to (mean, std) per observation value, puts a fixed
    `ObservationNorm` in front of the models ((observation - mean) / std), in training and
    evaluation alike: what `bbbench train` sets from random play (`bbbench.marl.training`).
    """

    observation_normalization: tuple[Any, Any] | None = None

    @property
    def task_id(self) -> str:
        return task_id(self.name)

    def get_env_fun(
        self, num_envs: int, continuous_actions: bool, seed: int | None, device: Any
    ) -> Callable[[], EnvBase]:
        config = copy.deepcopy(self.config)
        mode = "continuous" if continuous_actions else "discrete"
        task = self.task_id

        def make() -> EnvBase:
            env = bbbench.make_parallel(task, action_mode=mode, **config)
            return BbbenchWrapper(
                env,
                use_mask=True,
                done_on_any=False,
                categorical_actions=True,
                seed=seed,
                device=device,
            )

        return make

    def supports_continuous_actions(self) -> bool:
        return True

    def supports_discrete_actions(self) -> bool:
        return True

    def get_env_transforms(self, env: EnvBase) -> list[Transform]:
        if self.observation_normalization is None:
            return []
        mean, std = (
            torch.as_tensor(value, dtype=torch.float32) for value in self.observation_normalization
        )
        keys = [(group, "observation") for group in self.group_map(env)]
        return [ObservationNorm(loc=mean, scale=std, in_keys=keys, standard_normal=True)]

    def max_steps(self, env: EnvBase) -> int:
        return bbbench.spec(self.task_id).max_episode_steps

    def has_render(self, env: EnvBase) -> bool:
        return True

    def group_map(self, env: EnvBase) -> dict[str, list[str]]:
        return env.group_map

    def _keys(self, env: EnvBase, keep: str) -> Composite | None:
        spec = env.observation_spec.clone()
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
        return env.full_action_spec

    @staticmethod
    def env_name() -> str:
        return ENV_NAME


class BbbenchTask(Task):
    """bbbench's latest multi-bot and team tasks, for BenchMARL."""

    MULTIBALANCE_V1 = None
    MULTIBUMPS_V1 = None
    BEAMCARRY_V0 = None
    BEAMCARRYBUMPS_V0 = None
    CONVOY_V0 = None

    @staticmethod
    def associated_class():
        return BbbenchTaskClass

    def get_from_yaml(self, path: str | None = None) -> TaskClass:
        """The task with its configuration from bbbench's own YAML (or `path`)."""
        file = Path(path) if path else CONF / ENV_NAME / f"{self.name.lower()}.yaml"
        return self.get_task(config=_read_yaml_config(str(file)))


for _task in BbbenchTask:
    task_config_registry[f"{ENV_NAME}/{_task.name.lower()}"] = _task
