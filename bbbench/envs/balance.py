"""`BalanceEnv`: the single-bot environment every single-bot task runs in."""

from __future__ import annotations

import math
import time
from typing import Any, ClassVar

import numpy as np
from gymnasium import Env

from bbbench.envs.scene import Scene, render_ready, requested_task
from bbbench.tasks.spec import TRAINING_SEEDS, TaskSpec
from bbbench.tasks.suite import spec

RENDER_WIDTH, RENDER_HEIGHT = 320, 240  # pixels of an "rgb_array" frame
_CAMERA_DISTANCE = 2.2  # m from the bot
# deg from the bot's side, towards its back: the lean is seen from the side and the
# ground ahead of it in depth.
_CAMERA_YAW_FROM_SIDE = 50.0
_CAMERA_PITCH = -25.0  # deg
_AGENT = ["bot_0"]  # the one bot, named as a multi-bot env names its agents


class BalanceEnv(Env):
    """One balancing bot in a pybullet world: the Gymnasium env of every single-bot task.

    ## Description

    A task ID (`gymnasium.make("bbbench/Bumps-v2")`) is this class under a subclass of
    its own (`bbbench.envs.task_envs`), made from its row of the suite
    (`bbbench.spec(id)`): its robot, scenario, ground, command schedule, sensors and
    reward. Each task's page (docs/environments/, or `bbbench list TASK`) gives its
    spaces, reward, keywords and scores, printed from the code and the board.

    ## Action Space

    The robot's (`TaskSpec.robot`, docs/robots.md). The two-wheel bot's default is
    `Discrete(9)`, a change of the commanded wheel speed per step (the tutorial's
    table); `action_mode="continuous"` takes `Box(-1, 1, (1,), float32)`. An action
    outside the space, or NaN, raises `ValueError`: nothing is clamped silently.

    ## Observation Space

    `Box(n,)` of `float32`, each value named by the task's layout
    (`bbbench.tasks.suite.agent_layout(id)`): the robot's values (the shared five
    first: pitch, pitch rate, wheel speed, wheel command, target velocity), then what
    the scenario adds; with `height_scan=True`, where the task takes it, the ground's
    heights ahead.

    ## Rewards

    The task's (`bbbench.tasks.reward`): on the latest versions `StayUpReward`, 0 to 0.1
    a step, in which staying up never costs. `info` carries its two terms
    (`"reward_upright"`, `"reward_velocity"`) and the scenario's metrics.

    ## Starting State

    The bot at the origin heading along +y, leaning by U(-0.1, 0.1) rad. One integer
    decides an episode: `reset(seed=s)` plays episode s; `reset()` a training seed
    below 2**31 drawn from `np_random` (`info["episode_seed"]`). The evaluation seeds
    (`spec(id).eval_seeds`) lie at or above 2**31, the validation seeds above those.

    ## Episode End

    - Termination: a fall, the torso tilted more than 1 rad from vertical.
    - Truncation: the task's `max_episode_steps` (1500, 15 s), decided by the env's scene
      (`Scene.truncated`), also without Gymnasium's `TimeLimit`, which `gymnasium.make`
      adds at the same step. `gymnasium.make(id, max_episode_steps=N)` can end episodes
      sooner (its wrapper), not later: `bbbench.make(id, max_episode_steps=N)` sets both.

    ## Arguments

    `action_mode`, `render_mode` (`None`, `"rgb_array"` or `"human"`), `difficulty`
    (terrain tasks), `height_scan`, `max_episode_steps`, and one keyword per perturbation
    (`bbbench.tasks.perturbations`, docs/guides/robustness.md). The world is built at
    the first `reset()`; a pickled copy builds its own.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 100}

    def __init__(
        self,
        task: str | TaskSpec = "bbbench/FlatBalance-v1",
        action_mode: str | None = None,
        render_mode: str | None = None,
        difficulty: float | None = None,
        height_scan: bool | None = None,
        max_episode_steps: int | None = None,
        **unknown: Any,
    ) -> None:
        task = task if isinstance(task, TaskSpec) else spec(task)
        action_mode = action_mode or task.robot_model.default_action_mode
        task = requested_task(
            task,
            unknown,
            {
                "height_scan": height_scan,
                "difficulty": difficulty,
                "max_episode_steps": max_episode_steps,
            },
            action_mode,
            render_mode,
            self.metadata["render_modes"],
        )
        self.task = task
        self.action_mode = action_mode
        self.render_mode = render_mode
        self._human = render_mode == "human"
        self.action_space = task.action_space(action_mode)
        self.metadata = {**self.metadata, "render_fps": round(1.0 / task.control_dt)}
        self._scene = scene = Scene(task, action_mode, gui=self._human)
        scenario = scene.scenario
        self.observation_space = scenario.observation_space()
        self.metrics = scenario.metrics  # per-episode metrics: info keys, averaged per step
        # The step protocol (observe, then outcome), bound once: the hot path calls it.
        self._play = scenario.observe_and_score
        self._episode_seed = -1
        self._last_frame_time = 0.0

    @property
    def scene(self) -> Scene:
        """The episode's world, ground and bot, and what its seed drew (`scene.episode`)."""
        return self._scene

    # -- the gymnasium API ----------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        if options:
            raise ValueError(f"reset() takes no options, got {sorted(options)}")
        # One integer decides the episode: the seed given, or a training seed drawn
        # from np_random.
        episode_seed = int(self.np_random.integers(TRAINING_SEEDS.stop)) if seed is None else seed
        scene = self._scene
        states = scene.reset(episode_seed)
        self._episode_seed = episode_seed
        commands, targets = [scene.bots[0].wheel_command], [scene.target(0)]
        observations, _ = self._play(scene, _AGENT, states, commands, targets, episode_seed)
        if self._human:
            self._render_human()
        return observations[0], {"episode_seed": episode_seed}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        scene = self._scene
        command, state, target = scene.step_one(action)
        observations, outcome = self._play(
            scene, _AGENT, (state,), (command,), (target,), self._episode_seed
        )
        if self._human:
            self._render_human()
        return observations[0], outcome.rewards[0], outcome.over, scene.truncated, outcome.infos[0]

    def render(self) -> np.ndarray | None:
        if not render_ready(self):
            return None
        self._scene.scenario.draw(self._scene)  # what the camera would not see (a course)
        if self.render_mode == "rgb_array":
            self._scene.ground.paint()
            target, yaw = self.camera()
            return self._scene.world.camera_image(
                target, _CAMERA_DISTANCE, yaw, _CAMERA_PITCH, (RENDER_WIDTH, RENDER_HEIGHT)
            )
        self._render_human()
        return None

    def close(self) -> None:
        self._scene.close()

    # -- internals ------------------------------------------------------------

    def camera(self) -> tuple[tuple[float, float, float], float]:
        """Where the camera looks (the axle, raised to the bot's middle height: steady
        while it leans) and its yaw (deg): it follows the bot, up the slopes too."""
        state = self._scene.bots[0].read()
        x, y, axle_height = state.axle
        heading = math.degrees(math.atan2(state.heading[1], state.heading[0]))
        return (x, y, axle_height + 0.15), heading - 90.0 + _CAMERA_YAW_FROM_SIDE

    def _render_human(self) -> None:
        target, yaw = self.camera()
        self._scene.world.client.resetDebugVisualizerCamera(
            _CAMERA_DISTANCE, yaw, _CAMERA_PITCH, target
        )
        # Real time: a frame per control step, no faster than the simulated clock.
        delay = self.task.control_dt - (time.perf_counter() - self._last_frame_time)
        if delay > 0:
            time.sleep(delay)
        self._last_frame_time = time.perf_counter()
