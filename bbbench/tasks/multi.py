"""`MultiBalanceEnv`: several balancing bots in one pybullet world, a PettingZoo ParallelEnv."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pybullet
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv

from bbbench.robots import FALL_TILT, BalanceBot, BotState
from bbbench.sim import World
from bbbench.tasks.actions import (
    ACTION_MODES,
    action_space,
    continuous_change,
    discrete_change,
)
from bbbench.tasks.group import NEIGHBOUR_SPEED_RANGE, Group, nearest_others, spawn_poses
from bbbench.tasks.observation import OBSERVATION_DTYPE, observation_space, sensed
from bbbench.tasks.sensors import PerfectSensors
from bbbench.tasks.spec import TRAINING_SEEDS, TaskSpec, episode_streams
from bbbench.terrain import load_ground

# m: where fallen bots are set aside, far beyond anything an episode reaches.
_SET_ASIDE_X = 1000.0
RENDER_WIDTH, RENDER_HEIGHT = 480, 360  # pixels of an "rgb_array" frame of the group
CAMERA_YAW, CAMERA_PITCH = 30.0, -50.0  # deg: from above and aside, the whole group in view


class MultiBalanceEnv(ParallelEnv):
    """Several balancing bots in one world: each keeps its balance and its target.

    ## Description

    `n_bots` copies of the suite's bot (see `bbbench.tasks.balance.BalanceEnv`
    for the robot) share one pybullet world. They start spread around a circle
    of radius 2.5 m, each heading for its centre (give or take 0.3 rad), so
    their paths cross: each must keep upright and follow its own target
    velocity without knocking the others over. The bots cannot steer; a bot
    avoids another by slowing down, stopping or backing off, at a cost in
    velocity tracking. A bot that falls leaves the world at once (as its
    agent leaves `env.agents`): it is no obstacle, and no neighbour, to the
    others.

    | Task            | Ground                   | Target velocity (m/s), per bot | Bots        |
    |-----------------|--------------------------|--------------------------------|-------------|
    | MultiBalance-v0 | flat                     | U(0.2, 0.8), held 2-5 s        | 4 (2 to 16) |
    | MultiBumps-v0   | smooth hills, difficulty | U(0.2, 0.8), held 2-5 s        | 4 (2 to 16) |

    MultiBumps' ground is a 12 x 12 m square of Bumps-v0's hills centred on
    the start circle, level within 0.5 m of the circle, flat ground around it.

    Agents are named `bot_0` ... `bot_{n-1}`. One `step()` sets every live
    bot's motors, advances the world once (one `stepSimulation`) and reads
    every bot.

    ## Action Space

    Per agent, the single-bot action space (`action_mode="discrete"`:
    `Discrete(9)`, `"continuous"`: `Box(-1, 1, (1,))`), a change of the
    commanded wheel speed, documented in `BalanceEnv`. `step()` takes a dict
    with one action for every agent in `env.agents`, and no other key.

    ## Observation Space

    Per agent, `Box(5 + 4K,)` of float32 (K = 3 nearest neighbours: 17
    values). The first 5 are the single-bot layout, unchanged (`BalanceEnv`):

    | Num    | Observation      | Min | Max | Unit | Meaning                            |
    |--------|------------------|-----|-----|------|------------------------------------|
    | 0-4    | single-bot       |     |     |      | `BalanceEnv`'s five, unchanged     |
    | 5 + 4k | right            | -5  | 5   | m    | neighbour k's distance to the right|
    | 6 + 4k | forward          | -5  | 5   | m    | its distance ahead                 |
    | 7 + 4k | right_velocity   | -10 | 10  | m/s  | its velocity minus this bot's, right|
    | 8 + 4k | forward_velocity | -10 | 10  | m/s  | the same, ahead                    |

    for k = 0 (nearest) to K - 1, measured horizontally in this bot's own frame
    (forward along its heading, right along its axle) between the bots' torso
    centres, with the axles' velocities. Neighbours are the other bots in the
    world (fallen ones have left it) within 5 m; slots beyond the bots in
    range are zeros. Relative velocities saturate at 10 m/s.

    ## Rewards

    Per agent, the suite's base reward (`bbbench.tasks.reward`):
    `0.1 * (1 - |pitch|) - 0.1 * |forward_velocity - target_velocity|`, at most
    0.1 per step. There is no collision penalty: a collision costs what it
    costs, a fall ends that bot's episode. `infos[agent]` carries the two
    terms, `"reward_upright"` and `"reward_velocity"`, and `"velocity_error"`,
    |forward_velocity - target_velocity| in m/s.

    ## Starting State

    An episode is decided by one integer seed, as in the single-bot tasks: the
    spawn circle's turn, each bot's place on it (spaced evenly, each moved by
    up to a quarter of the spacing), heading, initial lean U(-0.1, 0.1) rad
    and target schedule, and the terrain. `reset(seed=s)` plays episode s;
    `reset()` a training seed drawn from the env's generator (seeded by the
    last `reset(seed=...)`); `infos[agent]["episode_seed"]` says which.
    `bbbench.spec(id).eval_seeds` are the evaluation seeds.

    ## Episode End

    - Termination, per agent: its torso tilts more than 1 rad from vertical (a
      fall). It is terminated in that step's dicts, leaves `env.agents`, and
      its bot leaves the world; it is never revived.
    - Truncation: after 1500 steps (15 s) every agent left is truncated.
    - `step({})` once no agent is left returns empty dicts.

    ## Arguments

    ```python
    import bbbench

    env = bbbench.make_parallel("bbbench/MultiBalance-v0", n_bots=4, action_mode="discrete")
    ```

    - `n_bots`: 2 to 16 (default 4); changes the task's fingerprint.
    - `action_mode`: `"discrete"` (default) or `"continuous"`.
    - `render_mode`: `None` or `"rgb_array"` (480 x 360 frames showing the
      whole group, headless).
    - `difficulty` (MultiBumps only): in [0, 1], default 0.3.
    - `max_episode_steps`: the time limit, default 1500.

    ## Version History

    (appended from the suite's spec table)
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "bbbench_multibalance",
        "render_modes": ["rgb_array"],
        "render_fps": 100,
        "is_parallelizable": True,
    }

    def __init__(
        self,
        task: str | TaskSpec = "bbbench/MultiBalance-v0",
        n_bots: int | None = None,
        action_mode: str = "discrete",
        render_mode: str | None = None,
        difficulty: float | None = None,
        max_episode_steps: int | None = None,
        **unknown: Any,
    ) -> None:
        if not isinstance(task, TaskSpec):
            from bbbench.tasks.suite import spec

            task = spec(task)
        if task.group is None:
            raise ValueError(
                f"{task.id} is a single-bot task: make it with gymnasium.make or bbbench.make"
            )
        if unknown or (difficulty is not None and task.difficulty is None):
            flat = difficulty is not None and task.difficulty is None
            given = sorted(unknown) + (["difficulty"] if flat else [])
            accepted = "n_bots, action_mode, render_mode, max_episode_steps" + (
                ", difficulty" if task.difficulty is not None else ""
            )
            raise TypeError(
                f"unknown keyword argument(s) {given} for {task.id}: accepted keyword "
                f"arguments are {accepted}"
            )
        if n_bots is not None:
            task = task.with_n_bots(n_bots)
        if difficulty is not None:
            task = task.with_difficulty(difficulty)
        if max_episode_steps is not None:
            task = task.with_time_limit(max_episode_steps)
        if action_mode not in ACTION_MODES:
            raise ValueError(f"action_mode must be one of {ACTION_MODES}, got {action_mode!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be None or one of {self.metadata['render_modes']}, "
                f"got {render_mode!r}"
            )
        if not isinstance(task.sensors, PerfectSensors) or task.sensors.delay_steps:
            raise ValueError(f"{task.id}: multi-bot tasks observe through perfect sensors only")
        self.task = task
        self.group = group = task.group
        self.action_mode = action_mode
        self.render_mode = render_mode
        self.metadata = {
            **self.metadata,
            "name": f"bbbench_{task.name.lower()}",  # bbbench_multibumps, ...
            "render_fps": round(1.0 / task.control_dt),
        }
        self.possible_agents = [f"bot_{i}" for i in range(group.n_bots)]
        self.agents: list[str] = []
        self._index = {agent: i for i, agent in enumerate(self.possible_agents)}
        self._action_space = action_space(action_mode)
        self._observation_space = agent_observation_space(group)
        self._observation_size = self._observation_space.shape[0]
        self._reward_weights = (task.reward.upright, task.reward.velocity)
        self._change = discrete_change if action_mode == "discrete" else continuous_change
        self._world = World(time_step=task.control_dt, substeps=task.physics_substeps)
        self._bots: list[BalanceBot] | None = None  # built with the world, on the first reset
        self._np_random: np.random.Generator | None = None
        self._targets = np.zeros((group.n_bots, 1))
        self._live: list[int] = []  # indices of the bots in self.agents, in order
        self._live_bots: list[BalanceBot] = []  # and the bots themselves
        self._ended_at: dict[str, int] = {}  # agent -> step its episode ended
        self._states: list[BotState] = []
        self._steps = 0

    # -- spaces -----------------------------------------------------------------

    def observation_space(self, agent: str) -> spaces.Box:
        self._check_agent(agent)
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Space:
        self._check_agent(agent)
        return self._action_space

    def _check_agent(self, agent: str) -> None:
        if agent not in self._index:
            raise ValueError(
                f"unknown agent {agent!r}: {self.task.id} with {self.group.n_bots} bots has "
                f"agents {self.possible_agents[0]!r} to {self.possible_agents[-1]!r}"
            )

    # -- the PettingZoo parallel API ----------------------------------------------

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        # No options are defined; PettingZoo's API test passes some, and expects them ignored.
        if seed is not None:
            self._np_random, _ = seeding.np_random(seed)
            episode_seed = int(seed)
        else:
            if self._np_random is None:
                self._np_random, _ = seeding.np_random()
            episode_seed = int(self._np_random.integers(TRAINING_SEEDS.stop))
        if self._bots is None:
            self._build_world()
        task, group = self.task, self.group
        streams = episode_streams(episode_seed)
        self._ground.reset(streams.terrain)
        poses = spawn_poses(streams.start, group)
        pitches = streams.start.uniform(-task.initial_pitch, task.initial_pitch, size=group.n_bots)
        targets = np.array(
            [
                task.command.targets(streams.command, task.max_episode_steps, task.control_dt)
                for _ in range(group.n_bots)
            ]
        )
        self._targets = targets
        self._targets_by_step = targets.T.tolist()  # [step][bot], floats for the hot path
        # Drop every contact point of the last episode at once (see BalanceBot.reset).
        for bot in self._bots:
            bot.move_clear()
        pybullet.performCollisionDetection(self._client_id)
        for bot, ((x, y), yaw), pitch in zip(self._bots, poses, pitches, strict=True):
            bot.reset(
                pitch=float(pitch),
                yaw=yaw,
                xy=(x, y),
                ground_height=self._ground.spawn_height(x, y),
                drop_contacts=False,
            )
        self._steps = 0
        self._live = list(range(group.n_bots))
        self._live_bots = list(self._bots)
        self.agents = self.possible_agents[:]
        self._ended_at = {}
        self._states = [bot.read() for bot in self._bots]
        observations = self._observe(self._states, self._targets_by_step[0])
        infos = {agent: {"episode_seed": episode_seed} for agent in self.agents}
        return dict(zip(self.agents, observations, strict=True)), infos

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        agents = self.agents
        if not isinstance(actions, dict):
            raise TypeError(
                f"step() takes a dict of actions, one for each agent in env.agents, got "
                f"{type(actions).__name__} {actions!r:.60}"
            )
        if len(actions) != len(agents) or not all(agent in actions for agent in agents):
            self._refuse(actions)
        if not agents:
            return {}, {}, {}, {}, {}
        change, live_bots = self._change, self._live_bots
        for agent, bot in zip(agents, live_bots, strict=True):
            try:
                bot.command_wheel_speed(bot.wheel_command + change(actions[agent]))
            except ValueError as error:
                raise ValueError(f"action for {agent!r}: {error}") from None
        pybullet.stepSimulation(self._client_id)
        self._steps = steps = self._steps + 1
        # Only the bots still in the world: a fallen one was set aside.
        self._states = states = [bot.read() for bot in live_bots]
        every_target = self._targets_by_step[min(steps, len(self._targets_by_step) - 1)]
        targets = [every_target[i] for i in self._live]
        observations = self._observe(states, targets)
        upright_weight, velocity_weight = self._reward_weights
        truncated = steps >= self.task.max_episode_steps
        rewards, terminations, truncations, infos = {}, {}, {}, {}
        fallen_any = False
        for agent, state, target in zip(agents, states, targets, strict=True):
            # reward.reward_terms, inlined on the hot path (tests/test_multi.py checks they agree).
            error = abs(state.forward_velocity - target)
            upright = upright_weight * (1.0 - abs(state.pitch))
            velocity = -velocity_weight * error
            rewards[agent] = upright + velocity
            infos[agent] = {
                "reward_upright": upright,
                "reward_velocity": velocity,
                "velocity_error": error,
            }
            truncations[agent] = truncated
            fallen = terminations[agent] = state.tilt > FALL_TILT
            fallen_any |= fallen
        returned = dict(zip(agents, observations, strict=True))
        if truncated:
            self._end(agents, steps)
        elif fallen_any:
            self._end([agent for agent in agents if terminations[agent]], steps)
        return returned, rewards, terminations, truncations, infos

    def _end(self, ended: list[str], steps: int) -> None:
        """Take the agents whose episodes ended out of `agents`, and their bots out of the world."""
        for agent in ended:
            self._ended_at[agent] = steps
            i = self._index[agent]
            # Far from everything and from each other, until the next reset.
            self._bots[i].set_aside((_SET_ASIDE_X + 10.0 * i, 0.0, 10.0))
        gone = set(ended)
        kept = [
            (agent, i, bot, state)
            for agent, i, bot, state in zip(
                self.agents, self._live, self._live_bots, self._states, strict=True
            )
            if agent not in gone
        ]
        self.agents = [agent for agent, *_ in kept]
        self._live = [i for _, i, _, _ in kept]
        self._live_bots = [bot for *_, bot, _ in kept]
        self._states = [state for *_, state in kept] or self._states

    def _refuse(self, actions: dict[str, Any]) -> None:
        """Raise the error that says what is wrong with the keys of `actions`."""
        for agent in actions:
            if agent not in self._index:
                self._check_agent(agent)
            if agent not in self.agents:
                ended = self._ended_at.get(agent)
                when = (
                    f"its episode ended at step {ended}"
                    if ended is not None
                    else "the episode has not been reset"
                )
                raise ValueError(
                    f"action for {agent!r}, which is not in env.agents ({when}): step() takes "
                    f"one action for each agent in env.agents and no other"
                )
        missing = [agent for agent in self.agents if agent not in actions]
        raise ValueError(
            f"no action for live agent(s) {', '.join(map(repr, missing))}: step() takes one "
            f"action for each agent in env.agents ({len(self.agents)} now)"
        )

    def _observe(self, states: list[BotState], targets: list[float]) -> np.ndarray:
        """Observations of the bots in `states` (the live ones), one row each.

        Plain Python floats and one numpy sort: at 2-16 bots, numpy's per-call
        cost would outweigh its arithmetic (bench/bench_multi.py).
        """
        group = self.group
        k, reach, top = group.neighbours, group.neighbour_range, NEIGHBOUR_SPEED_RANGE
        fill = [0.0] * self._observation_size
        positions = [complex(state.position[0], state.position[1]) for state in states]
        velocities = [complex(*state.velocity) for state in states]
        nearest = nearest_others(positions, k)
        rows = []
        for i, state in enumerate(states):
            row = [
                *sensed(state.pitch, state.pitch_rate, state.wheel_speed),
                self._live_bots[i].wheel_command,
                targets[i],
            ]
            here, velocity, (forward_x, forward_y) = positions[i], velocities[i], state.heading
            turn = complex(forward_y, forward_x)  # i * conj(heading): world -> right + i ahead
            for j in nearest[i]:
                offset = (positions[j] - here) * turn
                if abs(offset) > reach:
                    break  # the rest are farther
                moving = (velocities[j] - velocity) * turn
                right, ahead = moving.real, moving.imag  # saturated at the sensor's range:
                right = top if right > top else -top if right < -top else right
                ahead = top if ahead > top else -top if ahead < -top else ahead
                row += (offset.real, offset.imag, right, ahead)
            row += fill[len(row) :]
            rows.append(row)
        return np.array(rows, dtype=OBSERVATION_DTYPE).reshape(len(states), -1)

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            from gymnasium import logger

            logger.warn(
                "render() was called without a render_mode; make the env with "
                'render_mode="rgb_array"'
            )
            return None
        if self._bots is None:
            raise RuntimeError(f"{self.task.id}: call reset() before render()")
        self._ground.paint()
        target, distance = self._camera()
        return self._world.camera_image(
            target, distance, CAMERA_YAW, CAMERA_PITCH, (RENDER_WIDTH, RENDER_HEIGHT)
        )

    def _camera(self) -> tuple[tuple[float, float, float], float]:
        """Where the camera looks, and from how far, to frame every bot."""
        positions = np.array([state.position for state in self._states])
        low, high = positions.min(axis=0), positions.max(axis=0)
        center = (low + high) / 2.0
        spread = float(np.hypot(*(high - low)[:2]))
        return (float(center[0]), float(center[1]), 0.2), max(2.0, 0.8 * spread + 1.5)

    def close(self) -> None:
        self._world.close()
        self._bots = None
        self.agents = []

    # -- internals ------------------------------------------------------------

    def _build_world(self) -> None:
        client = self._world.client
        self._client_id = self._world.client_id
        self._ground = load_ground(client, self.task.terrain)
        self._bots = [BalanceBot(client) for _ in self.possible_agents]

    def __getstate__(self) -> dict[str, Any]:
        # As BalanceEnv: the world pickles as a description; a copy builds its own.
        state = self.__dict__.copy()
        state["_bots"] = None
        state["agents"] = []
        state["_live"] = []
        state["_live_bots"] = []
        state["_states"] = []
        state.pop("_ground", None)
        state.pop("_client_id", None)
        return state


def agent_observation_space(group: Group) -> spaces.Box:
    """One bot's observation space: the single-bot layout, then its neighbours'."""
    single = observation_space()
    low, high = group.bounds()
    return spaces.Box(
        low=np.concatenate([single.low, low]).astype(OBSERVATION_DTYPE),
        high=np.concatenate([single.high, high]).astype(OBSERVATION_DTYPE),
        dtype=OBSERVATION_DTYPE,
    )


def _version_history() -> str:
    from bbbench.tasks.suite import SUITE

    return "\n".join(
        f"    - {task.name}: {entry}"
        for task in SUITE.values()
        if task.multi_agent
        for entry in task.version_history
    )


MultiBalanceEnv.__doc__ = MultiBalanceEnv.__doc__.replace(
    "    (appended from the suite's spec table)\n", _version_history() + "\n"
)
