"""The worlds of a batch as one process plays them: `WorldSlice` (a contiguous share of
the worlds, each a `MultiBalanceEnv`), the arrays they read actions from and write
results to (`Buffers`, in shared memory when several processes share the batch), and a
worker process's loop (`serve`). `bbbench.envs.batched.BatchedEnv` drives them.

A batch's bots are in agent groups (`agent_groups`), each in its own spaces: one group,
`bot`, of every bot, or on a mixed team a group per robot; observations and actions are
held per group, everything else per bot.
"""

from __future__ import annotations

import signal
import traceback
from typing import Any, NamedTuple

import numpy as np

from bbbench.children import die_with_parent
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.tasks.scenario import Slots
from bbbench.tasks.spec import TaskSpec

# What `advance` does to each world.
LEAVE, STEP, RESET = 0, 1, 2
UNSEEDED = -1

# The one agent group of a task whose bots are all one robot (a mixed team has a group
# per robot): the name TorchRL's `PettingZooWrapper` gives agents bot_0 ... bot_{n-1}.
GROUP = "bot"


def agent_groups(task: TaskSpec) -> dict[str, tuple[int, ...]]:
    """The agent groups of a task's bots (at its `n_bots`), each in its own spaces: a
    group per robot on a mixed team (`TaskSpec.robot_groups`), and otherwise every bot in
    one group, `bot`. What BenchMARL trains a policy each for."""
    if task.mixed:
        return dict(task.robot_groups)
    return {GROUP: tuple(range(task.group.n_bots))}


def group_slots(task: TaskSpec) -> dict[str, Slots | None]:
    """How each agent group's rows read (`agent_groups`): its first bot's
    `Scenario.bot_slots`, since a group is one robot, so one layout; None for rows
    without slots. What the neighbour encoder and the trainer's normalizer read a row by."""
    scenario = task.scenario_class(task)
    return {group: scenario.bot_slots(bots[0]) for group, bots in agent_groups(task).items()}


class Buffers:
    """The arrays of a batch, one row per world, in (shared) memory: per bot its reward,
    ends and terms, and per agent group (`GroupLayout`) its bots' observations and
    actions, `observations[group]` (worlds, bots of the group, width)."""

    def __init__(self, worlds: int, bots: int, groups, terms, allocate=np.zeros) -> None:
        self.shapes = {
            "rewards": ((worlds, bots), np.float64),
            "terminated": ((worlds, bots), np.bool_),
            "truncated": ((worlds, bots), np.bool_),
            "live": ((worlds, bots), np.bool_),
            "terms": ((worlds, bots, len(terms)), np.float64),
            "episode_seed": ((worlds,), np.int64),
            "command": ((worlds,), np.int8),
            "seeds": ((worlds,), np.int64),
        }
        self.term_names = tuple(terms)  # the per-bot info values in `terms`, in order
        for name, (shape, dtype) in self.shapes.items():
            setattr(self, name, allocate(shape, dtype))
        self.groups: tuple[GroupLayout, ...] = tuple(groups)
        self.observations: dict[str, np.ndarray] = {}
        self.actions: dict[str, np.ndarray] = {}
        for group in groups:  # after the others: a worker's views come in this order
            n = len(group.bots)
            self.observations[group.name] = allocate((worlds, n, group.width), np.float32)
            self.actions[group.name] = allocate((worlds, n, *group.action_shape), group.dtype)


class GroupLayout(NamedTuple):
    """An agent group of a batch: its name, its bots' indices, their observation width
    and action shape and dtype (one robot's, on a mixed team)."""

    name: str
    bots: tuple[int, ...]
    width: int
    action_shape: tuple[int, ...]
    dtype: Any


def shared(context):
    """An allocator of numpy arrays over `context`'s shared memory, and the raw blocks."""
    blocks = {}

    def allocate(shape, dtype):
        size = int(np.prod(shape)) * np.dtype(dtype).itemsize
        block = context.RawArray("b", max(size, 1))
        blocks[len(blocks)] = (block, shape, dtype)
        return np.frombuffer(block, dtype=dtype, count=int(np.prod(shape))).reshape(shape)

    return allocate, blocks


class WorldSlice:
    """Worlds `start` to `stop - 1` of a batch, played in one process: each a
    `MultiBalanceEnv`, read from and written to its rows of `buffers`."""

    def __init__(
        self,
        task_id: str,
        env_kwargs: dict[str, Any],
        start: int,
        stop: int,
        buffers: Buffers,
        first: MultiBalanceEnv | None = None,
    ) -> None:
        self.start, self.stop = start, stop
        self.buffers = buffers
        self.envs = [
            first if (k == start and first is not None) else MultiBalanceEnv(task_id, **env_kwargs)
            for k in range(start, stop)
        ]
        self.agents = self.envs[0].possible_agents
        self.index = {agent: j for j, agent in enumerate(self.agents)}
        # Each agent's observation and action rows: (its group's arrays, its row there).
        self.rows = {}
        for group in buffers.groups:
            observed, chosen = buffers.observations[group.name], buffers.actions[group.name]
            for row, j in enumerate(group.bots):
                self.rows[self.agents[j]] = (observed, chosen, row)

    def advance(self) -> None:
        """Reset or step each world of the slice as its `command` says."""
        b = self.buffers
        for k, env in enumerate(self.envs, self.start):
            command = b.command[k]
            if command == STEP:
                self._step(k, env)
            elif command == RESET:
                seed = int(b.seeds[k])
                observations, infos = env.reset(seed=None if seed == UNSEEDED else seed)
                self._write(k, env, observations, None, {}, {}, infos)

    def _step(self, k: int, env: MultiBalanceEnv) -> None:
        rows = self.rows
        actions = {agent: rows[agent][1][k, rows[agent][2]] for agent in env.agents}
        observations, rewards, terminations, truncations, infos = env.step(actions)
        self._write(k, env, observations, rewards, terminations, truncations, infos)

    def _write(self, k, env, observations, rewards, terminations, truncations, infos) -> None:
        b, index, rows = self.buffers, self.index, self.rows
        for observed in b.observations.values():
            observed[k] = 0.0
        b.rewards[k] = 0.0
        b.terminated[k] = b.truncated[k] = False
        b.terms[k] = 0.0
        terms, names = b.terms[k], b.term_names
        for agent, observation in observations.items():
            j = index[agent]
            observed, _, row = rows[agent]
            observed[k, row] = observation
            if rewards is not None:
                b.rewards[k, j] = rewards[agent]
                b.terminated[k, j] = terminations[agent]
                b.truncated[k, j] = truncations[agent]
            info = infos[agent]
            terms[j] = [info[name] for name in names]
        live = env.agents
        b.live[k] = [agent in live for agent in self.agents]
        b.episode_seed[k] = env.episode_seed

    def close(self) -> None:
        for env in self.envs:
            env.close()


def serve(connection, task_id, env_kwargs, start, stop, blocks, layout, parent) -> None:
    """A worker process: its slice's worlds, advanced on each word from the batch. It dies
    with the process that made the batch, however that one dies."""
    die_with_parent(parent)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # not the script's own handler
    views = iter(
        np.frombuffer(block, dtype=dtype, count=int(np.prod(shape))).reshape(shape)
        for block, shape, dtype in (blocks[i] for i in range(len(blocks)))
    )
    buffers = Buffers(*layout, allocate=lambda shape, dtype: next(views))
    worlds_slice = None
    try:
        try:
            worlds_slice = WorldSlice(task_id, env_kwargs, start, stop, buffers)
        except Exception:  # the batch raises it, with the worker's traceback
            connection.send(traceback.format_exc())
            return
        connection.send(None)
        while True:
            word = connection.recv()
            if word == "close":
                break
            try:
                worlds_slice.advance()
                connection.send(None)
            except Exception:  # the batch raises it, with the worker's traceback
                connection.send(traceback.format_exc())
    except (EOFError, KeyboardInterrupt):
        pass
    finally:
        if worlds_slice is not None:
            worlds_slice.close()
        connection.close()
