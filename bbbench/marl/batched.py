"""`batched_env`: K worlds of a multi-bot or team task as one TorchRL env of
`batch_size=[K]`, as VMAS's envs are, so that a collector (BenchMARL's) calls the policy
once a step for every world.

    env = bbbench.marl.batched_env("bbbench/MultiBalance-v1", worlds=16, workers=2)
    rollout = env.rollout(100)  # (16, 100) of ("bot", "observation"): (4, 17) ...

Over `bbbench.envs.batched.BatchedEnv` (the worlds, in `workers` processes), with the
keys and specs of TorchRL's `PettingZooWrapper` over the task's parallel env (the one
group `bot`, or on a mixed team a group per robot, `bbbench.envs.worlds.agent_groups`,
as the wrapper's `group_map`; `("bot", "mask")`: the bots still in the episode; the root
`done` when every bot is), so a world plays, bit for bit, what `bbbench.make_parallel` plays from
the same seed, and BenchMARL's models and losses see the same keys. A bot out of the
episode reads zeros and reward 0, and its `done` stays set until its world resets
(tests/test_batched.py).

Seeds: `set_seed(S)` (BenchMARL passes its experiment's seed) makes the next reset of
every world play seed S + k in world k; after that each world draws its own
(`MultiBalanceEnv.reset()`), and a partial reset (`"_reset"`) restarts only the worlds
whose episode is done.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import torch
from tensordict import TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from bbbench.envs.batched import BatchedEnv
from bbbench.envs.worlds import GROUP


class BatchedTorchEnv(EnvBase):
    """A `BatchedEnv` under TorchRL's API (see the module's doc)."""

    def __init__(self, env: BatchedEnv, device: Any = "cpu") -> None:
        worlds, bots = env.num_worlds, env.n_bots
        super().__init__(
            batch_size=torch.Size([worlds]), device=device, allow_done_after_reset=True
        )
        self.env = env
        agents = env.possible_agents
        self.group_map = {group: [agents[i] for i in bots] for group, bots in env.groups.items()}
        # Each group's bots, as an index into a (worlds, bots) array (all: a view, no copy).
        self._bots = {
            group: np.asarray(bots) if env.task.mixed else slice(None)
            for group, bots in env.groups.items()
        }
        self._seed: int | None = None
        self._live = np.ones((worlds, bots), dtype=bool)
        self._make_specs(worlds)

    def _make_specs(self, worlds: int) -> None:
        env, device, root = self.env, self.device, (worlds,)
        observed, chosen, rewards, ends = {}, {}, {}, {}

        def flags(shape):
            return {
                key: Categorical(2, shape=(*shape, 1), dtype=torch.bool, device=device)
                for key in ("done", "terminated", "truncated")
            }

        for name, bots in env.groups.items():
            group = (worlds, len(bots))
            space, action = env.group_spaces[name]
            shape = (*group, space.shape[0])
            info = {
                term: Unbounded(shape=group, dtype=torch.float32, device=device)
                for term in env.buffers.term_names
            }
            observed[name] = Composite(
                observation=Bounded(
                    torch.tensor(np.broadcast_to(space.low, shape)),
                    torch.tensor(np.broadcast_to(space.high, shape)),
                    shape=shape,
                    dtype=torch.float32,
                    device=device,
                ),
                mask=Categorical(2, shape=group, dtype=torch.bool, device=device),
                info=Composite(info, shape=group),
                shape=group,
            )
            if hasattr(action, "n"):
                spec = Categorical(int(action.n), shape=group, dtype=torch.int64, device=device)
            else:
                spec = Bounded(
                    float(action.low.min()),
                    float(action.high.max()),
                    shape=(*group, *action.shape),
                    dtype=torch.float32,
                    device=device,
                )
            chosen[name] = Composite(action=spec, shape=group)
            reward = Unbounded(shape=(*group, 1), device=device)
            rewards[name] = Composite(reward=reward, shape=group)
            ends[name] = Composite(flags(group), shape=group)
        self.observation_spec = Composite(observed, shape=root)
        self.action_spec = Composite(chosen, shape=root)
        self.reward_spec = Composite(rewards, shape=root)
        self.done_spec = Composite({**flags(root), **ends}, shape=root)

    # -- EnvBase ----------------------------------------------------------------------

    def _set_seed(self, seed: int | None) -> None:
        self._seed = seed

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        which = np.ones(self.env.num_worlds, dtype=bool)
        if tensordict is not None and "_reset" in tensordict:
            which = tensordict.get("_reset").reshape(-1).numpy().copy()
        seed, self._seed = self._seed, None
        if seed is not None and not which.all():
            which[:] = True  # a new seed restarts every world on it
        self.env.reset_worlds(which, seed)
        self._live = self.env.buffers.live.copy()
        ended = np.zeros_like(self._live)
        return self._output(ended, ended, reward=False)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        actions = {
            group: tensordict.get((group, "action")).detach().cpu().numpy() for group in self._bots
        }
        out_before = ~self._live
        self.env.step_worlds(actions if self.env.task.mixed else actions[GROUP])
        b = self.env.buffers
        self._live = b.live.copy()
        # A bot out of the episode before this step stays done (as PettingZooWrapper).
        return self._output(b.terminated | out_before, b.truncated | out_before, reward=True)

    def _output(self, terminated: np.ndarray, truncated: np.ndarray, reward: bool):
        """A new tensordict of the buffers' rows: a clone of a zero template, written
        through numpy views (building one key by key validates every value, and cost as
        much as the policy call at 16 worlds: docs/performance.md)."""
        b = self.env.buffers
        out = (self._step_template if reward else self._reset_template).clone()
        done = terminated | truncated
        ends = (("done", done), ("terminated", terminated), ("truncated", truncated))
        for group, bots in self._bots.items():
            rows = out.get(group)
            np.copyto(rows.get("observation").numpy(), b.observations[group])
            np.copyto(rows.get("mask").numpy(), b.live[:, bots])
            info = rows.get("info")
            for i, name in enumerate(b.term_names):
                np.copyto(info.get(name).numpy(), b.terms[:, bots, i], casting="same_kind")
            for key, value in ends:
                np.copyto(rows.get(key).numpy()[..., 0], value[:, bots])
            if reward:
                np.copyto(
                    rows.get("reward").numpy()[..., 0], b.rewards[:, bots], casting="same_kind"
                )
        for key, value in ends:
            np.copyto(out.get(key).numpy()[..., 0], value.all(axis=1))
        return out

    @functools.cached_property
    def _reset_template(self) -> TensorDictBase:
        template = self.full_observation_spec.zero()
        template.update(self.full_done_spec.zero())
        return template

    @functools.cached_property
    def _step_template(self) -> TensorDictBase:
        template = self._reset_template.clone()
        template.update(self.full_reward_spec.zero())
        return template

    def close(self, *, raise_if_closed: bool = True) -> None:
        self.env.close()
        super().close(raise_if_closed=raise_if_closed)


def batched_env(
    task_id: str, worlds: int = 1, workers: int = 1, device: Any = "cpu", **env_kwargs: Any
) -> BatchedTorchEnv:
    """K = `worlds` worlds of the multi-bot or team task `task_id` as one TorchRL env of
    `batch_size=[K]`, stepped in `workers` processes; `env_kwargs` as `make_parallel`'s."""
    return BatchedTorchEnv(
        BatchedEnv(task_id, worlds=worlds, workers=workers, **env_kwargs), device=device
    )
