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

On a mixed team (`bbbench.spec(id).mixed`) each robot keeps its own spaces: the bots are
in a group per robot (`agent_groups`), and observations, actions and their spaces are
dicts by group, `{"wheel-legged": (K, 2, 31), "two-wheel": (K, 1, 19)}`, each group's
bots in the order of their indices; rewards, ends and infos stay (K, bots).

`workers=W` steps the worlds in W processes (this one and W - 1 others), each a
contiguous share, over shared memory: the results are the same bytes for any W.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from bbbench.envs.multi import MultiBalanceEnv
from bbbench.envs.worlds import (
    GROUP,
    LEAVE,
    RESET,
    STEP,
    UNSEEDED,
    Buffers,
    GroupLayout,
    WorldSlice,
    agent_groups,
    serve,
    shared,
)
from bbbench.tasks.suite import list_tasks, spec

# MiB a world takes, measured (docs/performance.md, "Several bots"): 29 for
# MultiBalance-v1, 39 for a world with terrain; a batch whose worlds would not fit in the
# machine is refused.
WORLD_MEMORY_MIB = 40

# How worker processes start: forked where the platform can (in milliseconds, and from any
# `__main__`, a notebook's or stdin's too); they run numpy and pybullet only, never torch.
START_METHOD = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"


class BatchedEnv:
    """K worlds of one multi-bot or team task, stepped together (see the module's doc).

    Args:
        task_id: a multi-bot or team task (`bbbench.list_tasks(multi_agent=True)`).
        worlds: K, a whole number of at least 1.
        workers: processes that step the worlds (this one included), 1 to K.
        **env_kwargs: the task's keywords, as `bbbench.make_parallel` takes them.

    `groups` maps each agent group to its bots' indices, and `group_spaces` to its one-bot
    (observation, action) spaces: one group, `bot`, but on a mixed team.
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
        self.groups = agent_groups(self.task)
        # Each group's one-bot (observation, action) spaces: its first bot's (one robot's),
        # for every bot and world; the one group `bot` but on a mixed team.
        self.group_spaces = {
            name: (first.observation_space(f"bot_{bots[0]}"), first.action_space(f"bot_{bots[0]}"))
            for name, bots in self.groups.items()
        }
        layouts = [
            _group_layout(name, bots, *self.group_spaces[name])
            for name, bots in self.groups.items()
        ]
        mixed = self.task.mixed  # a group per robot, each in its own spaces: dicts by group
        faces = (self.group_spaces, layouts, worlds, mixed)
        self.single_observation_space, self.observation_space = _faces(*faces, column=0)
        self.single_action_space, self.action_space = _faces(*faces, column=1)
        agent = self.possible_agents[0]
        _, probe = first.reset(seed=0)  # the info keys: the same from reset on
        terms = [key for key in probe[agent] if key != "episode_seed"]
        self._layout = (worlds, self.n_bots, tuple(layouts), terms)
        shares = np.array_split(np.arange(worlds), workers)
        self._slices = [(int(share[0]), int(share[-1]) + 1) for share in shares]
        if workers == 1:
            self.buffers = Buffers(*self._layout)
        else:
            context = multiprocessing.get_context(START_METHOD)
            allocate, self._blocks = shared(context)
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
    ) -> tuple[Any, dict[str, np.ndarray]]:
        """Every world's first observations, (K, bots, width) (a mixed team: a dict of
        them by group); world k seeded `seed + k` (or `seed[k]`; None: each draws its
        own)."""
        self.reset_worlds(np.ones(self.num_worlds, dtype=bool), seed)
        self._autoreset[:] = False
        return self._observations(), self._infos()

    def step(self, actions) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict]:
        """Step every world by its bots' `actions`, (K, bots) (continuous: (K, bots, 1)
        also; a mixed team: a dict of them by group, (K, bots of the group, width)); a
        world that ended at the last step restarts instead. Rewards and ends are per bot,
        (K, bots)."""
        b = self.buffers
        self._put_actions(actions)
        b.command[:] = np.where(self._autoreset, RESET, STEP)
        b.seeds[:] = UNSEEDED
        self._advance()
        self._autoreset = ~b.live.any(axis=1)
        return (
            self._observations(),
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
        self._put_actions(actions)
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
                target=serve,
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

    def _observations(self) -> Any:
        observed = {group: rows.copy() for group, rows in self.buffers.observations.items()}
        return observed if self.task.mixed else observed[GROUP]

    def _put_actions(self, actions) -> None:
        """Check every group's actions whole (no world sees a bad one), then write them."""
        if not self.task.mixed:
            actions = {GROUP: actions}
        elif not (isinstance(actions, dict) and set(actions) == set(self.groups)):
            given = sorted(actions) if isinstance(actions, dict) else type(actions).__name__
            raise ValueError(
                f"actions {given}: a batched {self.task_id} takes a dict of actions by "
                f"group, one array for each of {sorted(self.groups)}"
            )
        checked = {}
        for group, chosen in actions.items():
            space = self.group_spaces[group][1]
            want = self.buffers.actions[group].shape
            checked[group] = _checked(np.asarray(chosen), want, space, self.task_id)
        for group, array in checked.items():
            self.buffers.actions[group][...] = array

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


def _checked(array: np.ndarray, want: tuple[int, ...], space: spaces.Space, task_id: str):
    """`array` as actions of shape `want` from `space`, or a one-line ValueError."""
    if array.shape != want and (*array.shape, 1) != want:
        raise ValueError(
            f"actions of shape {array.shape}: a batched {task_id} takes one action "
            f"per bot of each world, shape {want} (worlds, bots"
            f"{', 1' if len(want) == 3 and want[-1] == 1 else ''})"
        )
    array = array.reshape(want)
    if isinstance(space, spaces.Discrete):
        if not np.issubdtype(array.dtype, np.number):
            raise ValueError(f"actions of dtype {array.dtype}: {task_id} takes {space}")
        last = space.start + space.n - 1
        bad = (array < space.start) | (array > last)
        if not np.issubdtype(array.dtype, np.integer):  # a policy's usual ints skip this
            bad |= ~np.isfinite(array) | (array != np.round(array))
        if bad.any():
            first = array.flat[int(np.argmax(bad.flat))]
            raise ValueError(
                f"action {first.item()!r}: {task_id}'s actions are {space}, whole numbers "
                f"from {space.start} to {last}; no world was stepped"
            )
    return array


def _group_layout(
    name: str, bots: tuple[int, ...], observed: spaces.Box, action: spaces.Space
) -> GroupLayout:
    """A group's layout in the batch's buffers, from its one-bot spaces."""
    discrete = isinstance(action, spaces.Discrete)
    shape, dtype = ((), np.int64) if discrete else (action.shape, np.float32)
    return GroupLayout(name, bots, observed.shape[0], shape, dtype)


def _faces(
    group_spaces: dict, layouts: list[GroupLayout], worlds: int, mixed: bool, column: int
) -> tuple[spaces.Space, spaces.Space]:
    """One bot's space and every world's, from column `column` (0: observation, 1: action)
    of each group's one-bot spaces: dicts by group on a mixed team, the one group's else."""
    one = {g.name: group_spaces[g.name][column] for g in layouts}
    many = {g.name: _batched(one[g.name], worlds, g) for g in layouts}
    return (spaces.Dict(one), spaces.Dict(many)) if mixed else (one[GROUP], many[GROUP])


def _batched(space: spaces.Space, worlds: int, group: GroupLayout) -> spaces.Space:
    """One bot's observation or action `space` for every bot of `group` in `worlds` worlds."""
    rows = (worlds, len(group.bots))
    if isinstance(space, spaces.Discrete):
        return spaces.MultiDiscrete(np.full(rows, space.n))
    shape = (*rows, *space.shape)
    low, high = np.broadcast_to(space.low, shape), np.broadcast_to(space.high, shape)
    return spaces.Box(low, high, dtype=space.dtype)


def _whole(value: Any, name: str, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
        raise ValueError(f"{name}={value!r}: expected a whole number of at least {least}")
    return int(value)


def _seeds(seed: int | Sequence[int] | None, worlds: int) -> np.ndarray:
    if seed is None:
        return np.full(worlds, UNSEEDED, dtype=np.int64)
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
