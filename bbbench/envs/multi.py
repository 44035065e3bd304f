"""`MultiBalanceEnv`: several balancing bots in one pybullet world, a PettingZoo ParallelEnv."""

from __future__ import annotations

import warnings
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv

from bbbench.envs.scene import ActionError, Scene, render_ready, requested_task
from bbbench.robots import BotState
from bbbench.tasks.scenario import Outcome
from bbbench.tasks.spec import TRAINING_SEEDS, TaskSpec
from bbbench.tasks.suite import SUITE, spec

RENDER_WIDTH, RENDER_HEIGHT = 480, 360  # pixels of an "rgb_array" frame of the group
CAMERA_YAW, CAMERA_PITCH = 30.0, -50.0  # deg: from above and aside, the whole group in view


class MultiBalanceEnv(ParallelEnv):
    """Several bots in one pybullet world: the PettingZoo parallel env of every multi-bot
    and team task.

    ## Description

    `bbbench.make_parallel("bbbench/Swap-v0")` plays a task's row of the suite
    (`bbbench.spec(id)`): its robot, scenario (the crossings, Swap, the team columns),
    group of bots, ground, commands and reward. Each task's page (docs/environments/,
    or `bbbench list TASK`) gives its rules, spaces, keywords and scores, printed from
    the code and the board. Agents are `bot_0` ... `bot_{n-1}`; one `step()` sets every
    live bot's motors, advances the world once and reads every bot.

    ## Action Space

    Per agent, the robot's single-bot space (`Discrete(9)` on the two-wheel bot,
    `Discrete(27)` on the steering robot; `action_mode="continuous"`: a `Box`), grown by
    the message values on a task with a channel (`bbbench.tasks.channel`).
    `step()` takes one action for every agent in `env.agents`; actions for agents whose
    episode has ended are ignored (TorchRL sends one per possible agent), and an unknown
    agent, an action outside the space or NaN is refused with `ValueError`.

    ## Observation Space

    Per agent, `Box(n,)` of `float32`, named value by value by the scenario's layout
    (`bbbench.tasks.suite.agent_layout(id)`): the robot's values, then what the scenario
    adds (the goal, the coupling's readings), then the neighbours' slots
    (`Scenario.slots`): each bot sees only its nearest neighbours within range, in its
    own frame, zeros in empty slots.

    ## Rewards

    The scenario's (`Scenario.outcome`): each bot's own shared reward on the crossings
    and Swap, the team's on the team tasks (every agent gets it). `infos[agent]` carries
    the reward's terms, the scenario's metrics and `"episode_seed"`, with the same keys
    at reset and at every step.

    ## Starting State

    One integer decides an episode (`reset(seed=s)`; `reset()` draws a training seed;
    `infos[agent]["episode_seed"]` says which): the bots' places, headings, leans,
    targets and the ground. `bbbench.spec(id).eval_seeds` are the evaluation seeds.

    ## Episode End

    - Termination: a bot that falls is terminated, leaves `env.agents` and, on the
      crossings and Swap, the world. On a team task a fall (or a broken tether) ends
      every agent's episode (multiwalker's `terminate_on_fall`).
    - Truncation: every agent left, after the task's `max_episode_steps` (1500).
    - `step({})` once no agent is left returns empty dicts.

    ## Arguments

    `n_bots` (the task's range), `action_mode`, `render_mode` (`None` or `"rgb_array"`),
    `difficulty` (on ground that takes one), `max_episode_steps`, on a task with a
    message channel `message_width`, `comm_range` and `mute_messages`
    (`bbbench.tasks.channel`), and one keyword per perturbation
    (`bbbench.tasks.perturbations`).

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
        task: str | TaskSpec = "bbbench/MultiBalance-v1",
        n_bots: int | None = None,
        action_mode: str | None = None,
        render_mode: str | None = None,
        difficulty: float | None = None,
        max_episode_steps: int | None = None,
        **unknown: Any,
    ) -> None:
        options = {"n_bots": n_bots, "max_episode_steps": max_episode_steps}
        options["difficulty"] = difficulty  # in this order in the messages
        task = task if isinstance(task, TaskSpec) else spec(task)
        action_mode = action_mode or task.default_action_mode  # a mixed team: continuous
        modes = self.metadata["render_modes"]
        task = requested_task(
            task, unknown, options, action_mode, render_mode, modes, several_bots=True
        )
        self.task = task
        self.group = group = task.group
        self.action_mode = action_mode
        self.render_mode = render_mode
        self.metadata = _metadata(self.metadata, task)
        self.possible_agents = [f"bot_{i}" for i in range(group.n_bots)]
        self.agents: list[str] = []
        self.agent_index = {agent: i for i, agent in enumerate(self.possible_agents)}
        self._action_spaces = task.action_spaces(action_mode)  # on a mixed team, per robot
        # The episode's world, ground and bots, and what its seed drew (`scene.episode`).
        self.scene = scene = Scene(task, action_mode)
        self._scenario = scenario = scene.scenario
        self._observation_spaces = list(map(scenario.bot_observation_space, range(group.n_bots)))
        self.metrics = scenario.metrics  # per-episode metrics: info keys, averaged per bot-step
        self._np_random: np.random.Generator | None = None
        self._episode_seed = -1
        self.ended_at: dict[str, int] = {}  # agent -> step its episode ended
        # The scenario's `Outcome` of the last reset or step, for the live bots then: which
        # fell, and why bots' episodes ended (what results record on team tasks).
        self.outcome: Outcome | None = None
        self._states: list[BotState] = []  # of the live bots, in order
        self._warned_options = False

    @property
    def episode_seed(self) -> int:
        """The seed of the episode being played (-1 before the first reset)."""
        return self._episode_seed

    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_spaces[self._check_agent(agent)]

    def action_space(self, agent: str) -> spaces.Space:
        return self._action_spaces[self._check_agent(agent)]

    def _check_agent(self, agent: str) -> int:  # its index, or a clear error
        if agent not in self.agent_index:
            raise ValueError(_unknown_agent(self, agent))
        return self.agent_index[agent]

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        if options and not self._warned_options:  # ignored, with a word, once
            self._warned_options = True
            warnings.warn(_ignored(options, self.task.id), stacklevel=2)
        self._np_random, episode_seed = _episode_seed(self._np_random, seed)
        scene = self.scene
        self._states = states = scene.reset(episode_seed)
        self._episode_seed = episode_seed
        self.agents = agents = self.possible_agents[:]
        self.ended_at = {}
        # At reset, infos with every step's keys: what the starting states would earn.
        observations, outcome = self._play(agents, states, scene.live_targets(0))
        infos = dict(zip(agents, outcome.infos, strict=True))
        return dict(zip(agents, observations, strict=True)), infos

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        agents, scene = self.agents, self.scene
        if not (isinstance(actions, dict) and len(actions) == len(agents)) or not all(
            agent in actions for agent in agents
        ):
            check_actions(actions, self)  # a clear error (or actions of ended agents: ignored)
        if not agents:
            return {}, {}, {}, {}, {}
        try:
            scene.act_live([actions[agent] for agent in agents])
        except ActionError as error:
            raise ValueError(f"action for {agents[error.index]!r}: {error}") from None
        # Only the bots still in the episode.
        self._states = states = scene.advance_live()
        steps = scene.steps
        observations, outcome = self._play(agents, states, scene.live_targets(steps))
        ends = [True] * len(agents) if outcome.over else outcome.fell
        terminations = dict(zip(agents, ends, strict=True))
        truncated = scene.truncated
        truncations = dict.fromkeys(agents, truncated)
        returned = dict(zip(agents, observations, strict=True))
        ended = agents if truncated else [agent for agent in agents if terminations[agent]]
        if ended:
            self._end(ended, steps)
        rewards = dict(zip(agents, outcome.rewards, strict=True))
        infos = dict(zip(agents, outcome.infos, strict=True))
        return returned, rewards, terminations, truncations, infos

    def _end(self, ended: list[str], steps: int) -> None:
        """Take the agents whose episodes ended out of `agents`; the scenario says what
        becomes of their bots."""
        gone = set(ended)
        for agent in ended:
            self.ended_at[agent] = steps
        kept = [k for k, agent in enumerate(self.agents) if agent not in gone]
        self._scenario.leave(self.scene, [self.agent_index[agent] for agent in ended])
        self.agents = [self.agents[k] for k in kept]
        self._states = [self._states[k] for k in kept] or self._states

    def _play(self, agents: list[str], states: list[BotState], targets: list[float]):
        """The step protocol (`Scenario.observe_and_score`); keeps the `outcome`."""
        commands = [bot.wheel_command for bot in self.scene.live_bots]
        observations, self.outcome = self._scenario.observe_and_score(
            self.scene, agents, states, commands, targets, self._episode_seed
        )
        return observations, self.outcome

    def render(self, mode: str | None = None) -> np.ndarray | None:
        """A frame of the whole group in the env's render mode. `mode` is for callers
        that pass one (RLlib's `ParallelPettingZooEnv` passes its own, None unless set):
        None or the env's own render mode."""
        if mode is not None and mode != self.render_mode:
            raise ValueError(_other_mode(mode, self.render_mode))
        return group_frame(self.scene, self._states) if render_ready(self) else None

    def camera(self) -> tuple[tuple[float, float, float], float]:
        """Where the camera looks, and from how far, to frame every bot."""
        return framing(self._states)

    def close(self) -> None:
        self.scene.close()
        self.agents = []

    def __getstate__(self) -> dict[str, Any]:
        # A copy has no world (the scene pickles without one) and no episode.
        return {**self.__dict__, "agents": [], "_states": []}


def _episode_seed(
    np_random: np.random.Generator | None, seed: int | None
) -> tuple[np.random.Generator | None, int]:
    """The env's generator and the episode's seed: `seed` (which seeds the generator, as
    Gymnasium's `np_random`), or a training seed drawn from the generator."""
    if seed is not None:
        return seeding.np_random(seed)[0], int(seed)
    if np_random is None:
        np_random, _ = seeding.np_random()
    return np_random, int(np_random.integers(TRAINING_SEEDS.stop))


def _metadata(metadata: dict[str, Any], task: TaskSpec) -> dict[str, Any]:
    """The env's metadata for `task`: its name (bbbench_multibumps ...) and frame rate."""
    name, fps = f"bbbench_{task.name.lower()}", round(1.0 / task.control_dt)
    return {**metadata, "name": name, "render_fps": fps}


def _unknown_agent(env: MultiBalanceEnv, agent: str) -> str:
    return (
        f"unknown agent {agent!r}: {env.task.id} with {env.group.n_bots} bots has agents "
        f"{env.possible_agents[0]!r} to {env.possible_agents[-1]!r}"
    )


def _other_mode(mode: str, own: str | None) -> str:
    return (
        f"render({mode!r}): this env renders in its own render_mode {own!r}; make it with "
        f"render_mode={mode!r} instead"
    )


def group_frame(scene: Scene, states: list[BotState]) -> np.ndarray:
    """A frame of the whole group: the ground painted, what the scenario draws, and
    every bot of `states` in view."""
    scene.ground.paint()
    scene.scenario.draw(scene)
    target, distance = framing(states)
    return scene.world.camera_image(
        target, distance, CAMERA_YAW, CAMERA_PITCH, (RENDER_WIDTH, RENDER_HEIGHT)
    )


def framing(states: list[BotState]) -> tuple[tuple[float, float, float], float]:
    """Where a camera looks, and from how far, to frame every bot of `states`."""
    positions = np.array([state.position for state in states])
    low, high = positions.min(axis=0), positions.max(axis=0)
    center = (low + high) / 2.0
    spread = float(np.hypot(*(high - low)[:2]))
    return (float(center[0]), float(center[1]), 0.2), max(2.0, 0.8 * spread + 1.5)


def check_actions(actions: dict[str, Any], env: MultiBalanceEnv) -> None:
    """Check the keys of `actions` (`env.step`'s dict) when they are not exactly
    `env.agents`: an unknown name, or a live agent without an action, is refused with one
    line that says what was given and what was expected. Actions for agents whose episode
    has ended are ignored (TorchRL and others send one for every possible agent)."""
    if not isinstance(actions, dict):
        raise TypeError(
            f"step() takes a dict of actions, one for each agent in env.agents, got "
            f"{type(actions).__name__} {actions!r:.60}"
        )
    unknown = [agent for agent in actions if agent not in env.agent_index]
    if unknown:
        raise ValueError(
            f"unknown agent(s) {', '.join(map(repr, unknown))} in step()'s actions: "
            f"{env.task.id} with {env.group.n_bots} bots has agents "
            f"{', '.join(env.possible_agents)}"
        )
    if not env.agents and not env.ended_at and actions:
        raise ValueError(
            f"actions for {', '.join(map(repr, actions))} before reset(): call reset() first"
        )
    missing = [agent for agent in env.agents if agent not in actions]
    if missing:
        raise ValueError(
            f"no action for live agent(s) {', '.join(map(repr, missing))}: step() takes one "
            f"action for each agent in env.agents ({len(env.agents)} now: "
            f"{', '.join(env.agents)}); got actions for {', '.join(actions) or 'none'}"
        )


def _ignored(options: Any, task_id: str) -> str:
    """The warning for options `reset()` ignores: where the first that is a keyword of
    `make_parallel` goes (`n_bots=8` for `options={"n_bots": 8}`)."""
    named = sorted(map(repr, options)) if isinstance(options, dict) else [repr(options)]
    keywords = ("n_bots", "difficulty", "max_episode_steps", "action_mode")
    given = [(k, options[k]) for k in keywords if isinstance(options, dict) and k in options]
    example = f"{given[0][0]}={given[0][1]!r}" if given else "max_episode_steps=500"
    return (
        f"{task_id}: reset() takes no options and ignored {', '.join(named)}; the task's "
        f"parameters are keywords of bbbench.make_parallel (n_bots, difficulty, "
        f"max_episode_steps, action_mode, and the perturbations), e.g. "
        f"bbbench.make_parallel({task_id!r}, {example})"
    )


def _version_history() -> str:
    return "\n".join(
        f"    - {task.name}: {entry}"
        for task in SUITE.values()
        if task.multi_agent
        for entry in task.version_history
    )


MultiBalanceEnv.__doc__ = MultiBalanceEnv.__doc__.replace(
    "    (appended from the suite's spec table)\n", _version_history() + "\n"
)
