"""`BatchedEnv`: K worlds of one multi-bot or team task, stepped together, as arrays.

    env = bbbench.make_batched("bbbench/MultiBalance-v1", worlds=16)
    observations, infos = env.reset(seed=0)         # (16, 4, 17) float32
    observations, rewards, terminations, truncations, infos = env.step(actions)  # (16, 4)

VMAS holds a batch of worlds in one env so that a learner calls its policy once a step
for all of them; BenchMARL's collector does that with any env whose `batch_size` is
`[K]` (`bbbench.marl.batched_env` is this env's TorchRL face). Each world here is the
task's PettingZoo env (`MultiBalanceEnv`), so world k plays, bit for bit, the episode
`bbbench.make_parallel` plays from the same seed (tests/test_batched.py).

Gymnasium's vector-env conventions hold: `reset(seed=S)` seeds world k with S + k (or
`seed[k]`, given a list); later episodes draw their seeds from each world's own
generator (as `MultiBalanceEnv.reset()` does); a world whose episode ended (no bot
left in it) restarts on its own at the next step (`AutoresetMode.NEXT_STEP`): that
step's actions for it are ignored and it returns the new episode's first
observations, rewards 0 and no ends.

Per bot, each step: the observation (zeros for a bot no longer in the episode), the
reward (0 for it), `terminated` and `truncated` at the step its episode ends only, and
in `infos["live"]` whether it is still in the episode after the step. `infos` also
carries each world's `episode_seed` (K,) and the reward's terms and the scenario's
metrics as (K, bots) arrays (the keys of the PettingZoo env's per-agent infos).

`workers=W` steps the worlds in W processes (this one and W - 1 others), each a
contiguous share, over shared memory: the results are the same bytes for any W.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import traceback
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from bbbench.children import die_with_parent
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.tasks.suite import list_tasks, spec

# MiB a world takes, measured (docs/performance.md, "Several bots"): 29 for
# MultiBalance-v1, 39 for a world with terrain; a batch whose worlds would not fit in the
# machine is refused.
WORLD_MEMORY_MIB = 40

# How worker processes start: forked where the platform can (in milliseconds, and from any
# `__main__`, a notebook's or stdin's too); they run numpy and pybullet only, never torch.
START_METHOD = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"

# What `advance` does to each world.
LEAVE, STEP, RESET = 0, 1, 2
_UNSEEDED = -1


class Buffers:
    """The arrays of a batch, one row per world, in (shared) memory."""

    def __init__(
        self,
        worlds: int,
        bots: int,
        width: int,
        action_shape,
        action_dtype,
        terms,
        allocate=np.zeros,
    ) -> None:
        self.shapes = {
            "actions": ((worlds, bots, *action_shape), action_dtype),
            "observations": ((worlds, bots, width), np.float32),
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


def _shared(context):
    """An allocator of numpy arrays over `context`'s shared memory, and the raw blocks."""
    blocks = {}

    def allocate(shape, dtype):
        size = int(np.prod(shape)) * np.dtype(dtype).itemsize
        block = context.RawArray("b", max(size, 1))
        blocks[len(blocks)] = (block, shape, dtype)
        return np.frombuffer(block, dtype=dtype, count=int(np.prod(shape))).reshape(shape)

    return allocate, blocks


class WorldSlice:
    """EnvCache `start` to `stop - 1` of a batch, played in one process: each a
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

    def advance(self) -> None:
        """Reset or step each world of the slice as its `command` says."""
        b = self.buffers
        for k, env in enumerate(self.envs, self.start):
            command = b.command[k]
            if command == STEP:
                self._step(k, env)
            elif command == RESET:
                seed = int(b.seeds[k])
                observations, infos = env.reset(seed=None if seed == _UNSEEDED else seed)
                self._write(k, env, observations, None, {}, {}, infos)

    def _step(self, k: int, env: MultiBalanceEnv) -> None:
        chosen = self.buffers.actions[k]
        index = self.index
        actions = {agent: chosen[index[agent]] for agent in env.agents}
        observations, rewards, terminations, truncations, infos = env.step(actions)
        self._write(k, env, observations, rewards, terminations, truncations, infos)

    def _write(self, k, env, observations, rewards, terminations, truncations, infos) -> None:
        b, index = self.buffers, self.index
        b.observations[k] = 0.0
        b.rewards[k] = 0.0
        b.terminated[k] = b.truncated[k] = False
        b.terms[k] = 0.0
        terms, names = b.terms[k], b.term_names
        for agent, observation in observations.items():
            j = index[agent]
            b.observations[k, j] = observation
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


def _serve(connection, task_id, env_kwargs, start, stop, blocks, layout, parent) -> None:
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


class BatchedEnv:
    """K worlds of one multi-bot or team task, stepped together (see the module's doc).

    Args:
        task_id: a multi-bot or team task (`bbbench.list_tasks(multi_agent=True)`).
        worlds: K, a whole number of at least 1.
        workers: processes that step the worlds (this one included), 1 to K.
        **env_kwargs: the task's keywords, as `bbbench.make_parallel` takes them.
    """

    metadata: ClassVar[dict[str, Any]] = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, task_id: str, worlds: int = 1, workers: int = 1, **env_kwargs: Any) -> None:
        if not spec(task_id).multi_agent:
            raise ValueError(
                f"{task_id} is a single-bot task: a batched env holds worlds of a multi-bot "
                f"or team task ({', '.join(list_tasks(multi_agent=True))}); for several "
                f"single-bot envs use gymnasium.make_vec({task_id!r}, num_envs=...)"
            )
        if env_kwargs.get("render_mode") is not None:
            raise ValueError(
                f"render_mode={env_kwargs['render_mode']!r}: a batched env does not render; "
                f"watch one world with bbbench.make_parallel({task_id!r}, "
                f"render_mode='rgb_array')"
            )
        worlds = _whole(worlds, "worlds", 1)
        self.num_worlds = worlds
        self.workers = workers = _whole(workers, "workers", 1)
        if workers > worlds:
            raise ValueError(
                f"workers={workers} for {worlds} world(s): each worker steps at least one "
                f"world; give workers from 1 to {worlds}"
            )
        check_memory(worlds)
        first = MultiBalanceEnv(task_id, **env_kwargs)  # the keywords checked here
        self.task = first.task
        self.task_id = task_id
        self.env_kwargs = dict(env_kwargs)
        self.possible_agents = list(first.possible_agents)
        self.n_bots = len(self.possible_agents)
        agent = self.possible_agents[0]
        self.single_observation_space = first.observation_space(agent)
        self.single_action_space = first.action_space(agent)
        width = self.single_observation_space.shape[0]
        self.observation_space = spaces.Box(
            np.broadcast_to(self.single_observation_space.low, (worlds, self.n_bots, width)),
            np.broadcast_to(self.single_observation_space.high, (worlds, self.n_bots, width)),
            dtype=np.float32,
        )
        if isinstance(self.single_action_space, spaces.Discrete):
            action_shape, action_dtype = (), np.int64
            self.action_space = spaces.MultiDiscrete(
                np.full((worlds, self.n_bots), self.single_action_space.n)
            )
        else:
            action_shape, action_dtype = self.single_action_space.shape, np.float32
            box = self.single_action_space
            shape = (worlds, self.n_bots, *box.shape)
            self.action_space = spaces.Box(
                np.broadcast_to(box.low, shape), np.broadcast_to(box.high, shape), dtype=box.dtype
            )
        _, probe = first.reset(seed=0)  # the info keys: the same from reset on
        terms = [key for key in probe[agent] if key != "episode_seed"]
        self._layout = (worlds, self.n_bots, width, action_shape, action_dtype, terms)
        shares = np.array_split(np.arange(worlds), workers)
        self._slices = [(int(share[0]), int(share[-1]) + 1) for share in shares]
        if workers == 1:
            self.buffers = Buffers(*self._layout)
        else:
            context = multiprocessing.get_context(START_METHOD)
            allocate, self._blocks = _shared(context)
            self.buffers = Buffers(*self._layout, allocate=allocate)
            self._context = context
        self._local = WorldSlice(task_id, self.env_kwargs, *self._slices[0], self.buffers, first)
        self._workers: list[tuple[Any, Any]] = []  # (process, connection), started lazily
        self._owner = os.getpid()  # a forked worker inherits this object: not its to close
        self._autoreset = np.zeros(worlds, dtype=bool)
        self._closed = False

    # -- the Gymnasium-style API ------------------------------------------------------

    def reset(
        self, seed: int | Sequence[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Every world's first observations, (K, bots, width); world k seeded `seed + k`
        (or `seed[k]`; None: each draws its own)."""
        self.reset_worlds(np.ones(self.num_worlds, dtype=bool), seed)
        self._autoreset[:] = False
        return self.buffers.observations.copy(), self._infos()

    def step(self, actions) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """Step every world by its bots' `actions`, (K, bots) (continuous: (K, bots, 1)
        also); a world that ended at the last step restarts instead."""
        b = self.buffers
        b.actions[...] = self._check_actions(actions)
        b.command[:] = np.where(self._autoreset, RESET, STEP)
        b.seeds[:] = _UNSEEDED
        self._advance()
        self._autoreset = ~b.live.any(axis=1)
        return (
            b.observations.copy(),
            b.rewards.copy(),
            b.terminated.copy(),
            b.truncated.copy(),
            self._infos(),
        )

    # -- worlds one at a time (the TorchRL face) ----------------------------------------

    def reset_worlds(self, which: np.ndarray, seed: int | Sequence[int] | None = None) -> None:
        """Reset the worlds where `which` (K,) holds, on `seed + k` (or `seed[k]`, or
        their own generators); the others stay as they are. Results in `self.buffers`."""
        b = self.buffers
        b.seeds[:] = _seeds(seed, self.num_worlds)
        b.command[:] = np.where(which, RESET, LEAVE)
        self._advance()

    def step_worlds(self, actions) -> None:
        """Step every world (none may have ended); results in `self.buffers`."""
        b = self.buffers
        b.actions[...] = self._check_actions(actions)
        b.command[:] = STEP
        self._advance()

    def _advance(self) -> None:
        if self._closed:
            raise RuntimeError(f"{self.task_id}: this batched env is closed")
        if self.workers > 1 and not self._workers:
            self._start_workers()
        try:
            for _, connection in self._workers:
                connection.send("advance")
            self._local.advance()
            failures = [connection.recv() for _, connection in self._workers]
        except (EOFError, BrokenPipeError) as error:
            raise RuntimeError(
                f"a worker process of the batched env ended ({type(error).__name__}): "
                f"make the env again"
            ) from None
        for failure in failures:
            if failure is not None:
                raise RuntimeError(f"a worker of the batched env failed:\n{failure}")

    def _start_workers(self) -> None:
        context = self._context
        for start, stop in self._slices[1:]:
            mine, theirs = context.Pipe()
            process = context.Process(
                target=_serve,
                args=(
                    theirs,
                    self.task_id,
                    self.env_kwargs,
                    start,
                    stop,
                    self._blocks,
                    self._layout,
                    os.getpid(),
                ),
                daemon=True,
            )
            process.start()
            theirs.close()
            self._workers.append((process, mine))
        for _, connection in self._workers:
            failure = connection.recv()
            if failure is not None:
                raise RuntimeError(f"a worker of the batched env failed to start:\n{failure}")

    def _check_actions(self, actions) -> np.ndarray:
        array = np.asarray(actions)
        want = self.action_space.shape
        if array.shape != want and (*array.shape, 1) != want:
            raise ValueError(
                f"actions of shape {array.shape}: a batched {self.task_id} takes one action "
                f"per bot of each world, shape {want} (worlds, bots"
                f"{', 1' if len(want) == 3 else ''})"
            )
        array = array.reshape(want)
        space = self.single_action_space
        if isinstance(space, spaces.Discrete):  # checked whole here: no world sees a bad one
            if not np.issubdtype(array.dtype, np.number):
                raise ValueError(f"actions of dtype {array.dtype}: {self.task_id} takes {space}")
            last = space.start + space.n - 1
            bad = (array < space.start) | (array > last)
            if not np.issubdtype(array.dtype, np.integer):  # a policy's usual ints skip this
                bad |= ~np.isfinite(array) | (array != np.round(array))
            if bad.any():
                first = array.flat[int(np.argmax(bad.flat))]
                raise ValueError(
                    f"action {first.item()!r}: {self.task_id}'s actions are {space}, whole numbers "
                    f"from {space.start} to {last}; no world was stepped"
                )
        return array

    def _infos(self) -> dict[str, np.ndarray]:
        b = self.buffers
        infos = {"live": b.live.copy(), "episode_seed": b.episode_seed.copy()}
        for i, name in enumerate(b.term_names):
            infos[name] = b.terms[:, :, i].copy()
        return infos

    def close(self) -> None:
        if self._closed or os.getpid() != self._owner:
            return
        self._closed = True
        for process, connection in self._workers:
            with contextlib.suppress(BrokenPipeError, OSError):
                connection.send("close")
            process.join(timeout=10)
            if process.is_alive():
                process.terminate()
            connection.close()
        self._workers = []
        self._local.close()

    def __del__(self) -> None:
        if not getattr(self, "_closed", True):
            self.close()

    def __repr__(self) -> str:
        return f"BatchedEnv({self.task_id!r}, worlds={self.num_worlds}, workers={self.workers})"


def _whole(value: Any, name: str, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
        raise ValueError(f"{name}={value!r}: expected a whole number of at least {least}")
    return int(value)


def _seeds(seed: int | Sequence[int] | None, worlds: int) -> np.ndarray:
    if seed is None:
        return np.full(worlds, _UNSEEDED, dtype=np.int64)
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        if seed < 0:
            raise ValueError(f"seed={seed}: expected a seed of at least 0")
        return np.arange(worlds, dtype=np.int64) + int(seed)
    seeds = list(seed)
    if len(seeds) != worlds or any(
        isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0 for s in seeds
    ):
        raise ValueError(
            f"seed={seed!r}: expected None, a seed, or {worlds} seeds (one per world) of at least 0"
        )
    return np.asarray(seeds, dtype=np.int64)


def check_memory(worlds: int) -> None:
    """`ValueError` if `worlds` worlds would not fit in this machine's memory."""
    machine = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**20
    if worlds * WORLD_MEMORY_MIB > machine:
        raise ValueError(
            f"worlds={worlds}: at about {WORLD_MEMORY_MIB} MiB a world that is "
            f"{worlds * WORLD_MEMORY_MIB / 1024:.0f} GiB, more than this machine's "
            f"{machine / 1024:.0f} GiB; give at most {int(machine // WORLD_MEMORY_MIB)} worlds"
        )
