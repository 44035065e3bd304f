"""stable-baselines3 `VecEnv`s of bbbench tasks: `make_vec`.

A multi-bot task trains by parameter sharing: every bot of every world is one
slot of the VecEnv, so one SB3 policy drives them all. `BotSlotsVecEnv` is
that adapter, written here rather than taken from SuperSuit 3.11.0, whose
route (`pettingzoo_env_to_vec_env_v1` + `concat_vec_envs_v1`) has no `seed()`
on its VecEnv, never marks time-limit truncation (so SB3 does not bootstrap
at the time limit) and, with `black_death_v3`, reports a fallen agent's done
one step late; docs/performance.md compares the two.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

from bbbench.envs.factory import make_parallel
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.tasks.suite import spec


class BotSlotsVecEnv(VecEnv):
    """Every bot of several multi-bot worlds as one slot of a stable-baselines3 VecEnv.

    Slot `w * n_bots + j` is agent `bot_j` of world `w`. A slot's episode is
    its bot's: it ends when the bot falls (`done`, `TimeLimit.truncated`
    False) or at the time limit (`done`, `TimeLimit.truncated` True, so SB3
    bootstraps), with the bot's last observation in `terminal_observation`
    and SB3's `info["episode"]` statistics (return, length). A world resets
    once all its bots have ended; until then the slot of a fallen bot is idle:
    zero observations and rewards, its actions ignored, closed by a `done`
    when the world resets (marked `info["idle"]`, and without `"episode"`,
    so SB3's episode statistics count real episodes only). The agents' own
    info (the reward's terms) is passed through.

    `seed(s)` makes world `w`'s next reset play episode seed `s + w`; the
    worlds draw their later episodes from their own generators, so a seeded
    run repeats exactly.
    """

    def __init__(self, envs: Sequence[MultiBalanceEnv]) -> None:
        if not envs:
            raise ValueError("BotSlotsVecEnv needs at least one multi-bot env")
        self.envs = list(envs)
        first = self.envs[0]
        self.agents = list(first.possible_agents)
        if any(env.possible_agents != self.agents for env in self.envs):
            raise ValueError("every world of a BotSlotsVecEnv must have the same agents")
        self.n_bots = len(self.agents)
        self._slots = {agent: j for j, agent in enumerate(self.agents)}
        agent = self.agents[0]
        super().__init__(
            len(self.envs) * self.n_bots,
            first.observation_space(agent),
            first.action_space(agent),
        )
        self._observations = np.zeros(
            (self.num_envs, *self.observation_space.shape), self.observation_space.dtype
        )
        self._returns = np.zeros(self.num_envs)
        self._lengths = np.zeros(self.num_envs, dtype=np.int64)
        self._world_seeds: list[int | None] = [None] * len(self.envs)
        self._actions: np.ndarray | None = None
        self._started = time.perf_counter()

    # -- the VecEnv API -------------------------------------------------------------

    def seed(self, seed: int | None = None) -> list[int | None]:
        self._world_seeds = [None if seed is None else seed + w for w in range(len(self.envs))]
        return [world_seed for world_seed in self._world_seeds for _ in self.agents]

    def reset(self) -> VecEnvObs:
        for world in range(len(self.envs)):
            self._reset_world(world, self._world_seeds[world])
        self._world_seeds = [None] * len(self.envs)
        return self._observations.copy()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        actions, self._actions = self._actions, None
        if actions is None:
            raise RuntimeError("step_wait() without step_async(): call step(actions)")
        if len(actions) != self.num_envs:
            raise ValueError(
                f"expected {self.num_envs} actions (one per bot slot: {len(self.envs)} worlds x "
                f"{self.n_bots} bots), got {len(actions)}"
            )
        rewards = np.zeros(self.num_envs, dtype=np.float32)
        dones = np.zeros(self.num_envs, dtype=bool)
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for world, env in enumerate(self.envs):
            base = world * self.n_bots
            observations, step_rewards, terminations, truncations, step_infos = env.step(
                {agent: actions[base + self._slots[agent]] for agent in env.agents}
            )
            for agent, reward in step_rewards.items():
                slot = base + self._slots[agent]
                rewards[slot] = reward
                self._returns[slot] += reward
                self._lengths[slot] += 1
                info = infos[slot] = step_infos[agent]  # a fresh dict every step
                if terminations[agent] or truncations[agent]:
                    dones[slot] = True
                    info["terminal_observation"] = observations[agent]
                    info["TimeLimit.truncated"] = truncations[agent] and not terminations[agent]
                    info["episode"] = {
                        "r": float(self._returns[slot]),
                        "l": int(self._lengths[slot]),
                        "t": round(time.perf_counter() - self._started, 6),
                    }
                    self._observations[slot] = 0.0
                else:
                    self._observations[slot] = observations[agent]
            if not env.agents:  # the world is over: close the idle slots, play the next
                for slot in range(base, base + self.n_bots):
                    if not dones[slot]:
                        dones[slot] = True
                        infos[slot] = {
                            "idle": True,
                            "terminal_observation": self._observations[slot].copy(),
                            "TimeLimit.truncated": False,
                        }
                self._reset_world(world, None)
        return self._observations.copy(), rewards, dones, infos

    def close(self) -> None:
        for env in self.envs:
            env.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [env.render() for env in self.envs]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self.envs[world], attr_name) for world in self._worlds(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        for world in set(self._worlds(indices)):
            setattr(self.envs[world], attr_name, value)

    def env_method(
        self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs
    ) -> list[Any]:
        return [
            getattr(self.envs[world], method_name)(*method_args, **method_kwargs)
            for world in self._worlds(indices)
        ]

    def env_is_wrapped(
        self, wrapper_class: type[gymnasium.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        return [False for _ in self._worlds(indices)]

    # -- internals ----------------------------------------------------------------

    def _worlds(self, indices: VecEnvIndices) -> list[int]:
        return [slot // self.n_bots for slot in self._get_indices(indices)]

    def _reset_world(self, world: int, seed: int | None) -> None:
        observations, infos = self.envs[world].reset(seed=seed)
        base = world * self.n_bots
        for j, agent in enumerate(self.agents):
            self._observations[base + j] = observations[agent]
            self.reset_infos[base + j] = infos[agent]
        self._returns[base : base + self.n_bots] = 0.0
        self._lengths[base : base + self.n_bots] = 0


def make_vec(task_id: str, n_envs: int = 1, **kwargs: Any) -> VecEnv:
    """A stable-baselines3 VecEnv of `n_envs` copies of any task of the suite.

    A single-bot task gives SB3's own `DummyVecEnv` of `n_envs` monitored envs;
    a multi-bot task a `BotSlotsVecEnv` of `n_envs` worlds, one slot per bot
    (`n_envs * n_bots` slots), for one policy shared by every bot. Keyword
    arguments go to each env (`n_bots=8`, `action_mode="continuous"`, ...).

        model = PPO("MlpPolicy", bbbench.make_vec("bbbench/MultiBalance-v1", n_envs=2))
    """
    if isinstance(n_envs, bool) or not isinstance(n_envs, int) or n_envs < 1:
        raise ValueError(f"n_envs must be a whole number >= 1, got {n_envs!r}")
    if spec(task_id).multi_agent:
        return BotSlotsVecEnv([make_parallel(task_id, **kwargs) for _ in range(n_envs)])

    return make_vec_env(task_id, n_envs=n_envs, env_kwargs=kwargs)
