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
    """Keep a two-wheeled balancing bot upright (and at its target velocity).

    ## Description

    The bot of the pybullet balancing-bot tutorial: a 0.8 kg torso, 0.2 x 0.05 x
    0.4 m, on two 0.1 m wheels of 0.1 kg on one axle; 1.0 kg and 0.5 m tall in
    all. The wheels' velocity servos hold a commanded wheel speed with at most
    0.6 N m of torque each, up to 24.6 rad/s (2.46 m/s). The bot is an inverted
    pendulum: left alone it falls; the agent keeps it up by changing the
    commanded wheel speed, driving the wheels under the torso.

    Every single-bot task of bbbench is this class (a subclass per task, in
    `bbbench.envs.task_envs`, made from the task's row, documents each) and shares its robot,
    action table, observation layout and reward; a task is a `TaskSpec` (see
    `bbbench.spec(id)`), and differs only in its ground, its command schedule
    and its sensors:

    | Task                | Ground                     | Target velocity (m/s)   | Sensors        |
    |---------------------|----------------------------|-------------------------|----------------|
    | FlatBalance-v1      | flat                       | 0                       | perfect        |
    | VelocityTracking-v1 | flat                       | U(-1, 1), held 2-5 s    | perfect        |
    | NoisySensors-v1     | flat                       | U(-1, 1), held 2-5 s    | biased, noisy  |
    | Bumps-v2            | steep short hills          | U(1, 2), held 2-5 s     | perfect        |
    | Obstacles-v2        | obstacle course, 0.05 m cells | U(1, 2), held 2-5 s  | perfect        |
    | Slopes-v2           | ramps up and down          | U(1, 2), held 2-5 s     | perfect        |

    The wheel-legged robot's tasks (LeggedFlatBalance-, LeggedVelocityTracking-,
    LeggedBumps- and LeggedObstacles-v0) play this class too, with the robot their row
    names (`TaskSpec.robot`): the reward, starting state, episode end and arguments below
    are theirs as well, and their own classes (`bbbench.envs.task_envs.LeggedBumpsEnv`, ...)
    document the robot's actions and observations (docs/robots.md).

    These are the latest versions, on the reward in which staying up never costs
    (Rewards, below). Each earlier version plays the same episodes under the
    first reward, and stays registered unchanged: FlatBalance-, VelocityTracking-
    and NoisySensors-v0; Bumps-, Obstacles- and Slopes-v1; and Bumps- and
    Obstacles-v0, gentler terrain at 0.2-0.8 m/s. The terrain tasks are hard for
    a hand-written controller (the PD baseline falls in about half their
    episodes); their classes (`BumpsEnv`, ...) document the design.

    NoisySensors: per episode, a pitch bias ~ N(0, 0.1) rad; per step, Gaussian
    noise of 0.05 rad on pitch, 0.01 rad/s on pitch rate, 0.05 rad/s on wheel
    speed (the tutorial's values). The reward always uses the true state.

    ## Action Space

    `action_mode="discrete"` (default): `Discrete(9)`, a change of the
    commanded wheel speed per step (the tutorial's table):

    | Num | Change of commanded wheel speed (rad/s) |
    |-----|-----------------------------------------|
    | 0   | -1.0                                    |
    | 1   | -0.5                                    |
    | 2   | -0.2                                    |
    | 3   | -0.01                                   |
    | 4   | 0.0                                     |
    | 5   | 0.01                                    |
    | 6   | 0.2                                     |
    | 7   | 0.5                                     |
    | 8   | 1.0                                     |

    `action_mode="continuous"`: `Box(-1, 1, (1,), float32)`, scaled to a change
    of -1.0 to 1.0 rad/s.

    The command is clamped to the wheel-speed limit, +-24.6 rad/s. An action
    outside the space (or NaN) raises `ValueError`; nothing is clamped silently.

    ## Observation Space

    `Box(5,)` of `float32`, the same for every single-bot task. Forward is the
    bot's own +y axis; angles are measured in the bot's own frame against
    gravity, so they mean the same whatever the heading or slope.

    | Num | Observation     | Min     | Max    | Unit  | Meaning                            |
    |-----|-----------------|---------|--------|-------|------------------------------------|
    | 0   | pitch           | -pi     | pi     | rad   | torso lean from vertical, + fwd    |
    | 1   | pitch_rate      | -34.907 | 34.907 | rad/s | gyro rate about the axle (1)       |
    | 2   | wheel_speed     | -50     | 50     | rad/s | wheel speed vs the torso (2)       |
    | 3   | wheel_command   | -24.6   | 24.6   | rad/s | speed the servos are told to hold  |
    | 4   | target_velocity | -2.46   | 2.46   | m/s   | forward velocity the task asks for |

    (1) saturates at 2000 deg/s, a common MEMS gyro's full scale. (2) what the
    encoders measure; saturates at 50 rad/s, about twice the motors' top speed.

    ### Height Scan

    `height_scan=True` (default False) appends 11 ground heights ahead of the
    bot: `Box(16,)`. Each is the ground's height at a point on the bot's
    heading, so many metres ahead of the axle, minus the axle's height (flat
    ground reads -0.1, the wheel radius), clipped to +-3 m; read from the
    episode's heightmap at the node nearest each point (so to within its
    resolution, 0.05 m cells on Bumps- and Obstacles-v1; no ray casts). The first
    five values are the blind observation above, unchanged; the blind layout
    stays the default, so one policy plays every task. A height-scan task is
    a different spec (`spec.with_height_scan()`) with its own fingerprint.

    | Num | Observation     | Min | Max | Unit | Ahead (m)        |
    |-----|-----------------|-----|-----|------|------------------|
    | 5   | height_scan_0  | -3  | 3   | m    | 0.0 (under the axle) |
    | 6   | height_scan_1  | -3  | 3   | m    | 0.1              |
    | 7   | height_scan_2  | -3  | 3   | m    | 0.2              |
    | 8   | height_scan_3  | -3  | 3   | m    | 0.3              |
    | 9   | height_scan_4  | -3  | 3   | m    | 0.4              |
    | 10  | height_scan_5  | -3  | 3   | m    | 0.5              |
    | 11  | height_scan_6  | -3  | 3   | m    | 0.6              |
    | 12  | height_scan_7  | -3  | 3   | m    | 0.7              |
    | 13  | height_scan_8  | -3  | 3   | m    | 0.8              |
    | 14  | height_scan_9  | -3  | 3   | m    | 0.9              |
    | 15  | height_scan_10 | -3  | 3   | m    | 1.0              |

    ## Rewards

    One reward for every task of a version (`bbbench.tasks.reward`), the sum of two
    terms, in which staying up never costs. From FlatBalance-v1, VelocityTracking-v1,
    NoisySensors-v1, Bumps-v2, Obstacles-v2 and Slopes-v2 on (`StayUpReward`):

        upright  = tolerance(|pitch|, bound 0.1 rad, width 0.5 rad)
        near     = tolerance(|velocity_error|, bound 0.1 m/s, width 0.25 m/s)
        toward   = ramp(|velocity_error|, bound 0.1 m/s, width 2.0 m/s)
        tracking = 0.9 * near + 0.1 * toward
        reward   = 0.1 * upright * (0.1 + 0.9 * tracking)

    where velocity_error = forward_velocity - target_velocity (the axle's true
    horizontal forward velocity, m/s), pitch is in rad, tolerance(x, bound,
    width) is 1 up to the bound, 1 - ((x - bound) / width)^2 beyond it and 0
    from bound + width on (dm_control's `rewards.tolerance`, quadratic), and
    ramp(x, bound, width) the same with a linear fall, 1 - (x - bound) /
    width: a long tail that pays a bot far from its target for moving towards
    it. Each step earns between 0 and 0.1,
    and 0.1 only upright and on target, so a 1500-step episode scores at most
    150; a fall forfeits the rest of the episode and never scores more.
    Standing still earns 0.01 a step far off target; doing the task up to 0.1.
    `info` after each step carries the two terms, `"reward_upright"` (0.01 *
    upright) and `"reward_velocity"` (0.09 * upright * tracking), whose sum is
    the reward, and `"velocity_error"`, |forward_velocity - target_velocity| in
    m/s (true, not sensed).

    The earlier versions (every -v0, and Bumps-, Obstacles- and Slopes-v1) keep
    the tutorial's form (`RewardWeights`):

        reward = 0.1 * (1 - |pitch|) - 0.1 * |forward_velocity - target_velocity|

    It is negative whenever the bot is 1 m/s or more off its target: on the -v1
    terrain, whose targets are 1-2 m/s, a bot that never fell but was held back
    scored less than one that fell at once (docs/tasks.md has the numbers).

    ## Starting State

    The bot stands at the origin, heading along +y, at rest on level ground (on
    terrain tasks, a level pad of radius 0.5 m), leaning by a pitch drawn
    uniformly from [-0.1, 0.1] rad (so doing nothing falls). An episode is
    decided by one integer seed: `reset(seed=s)` plays episode s; `reset()`
    plays a training seed below 2**31 drawn from the env's `np_random` (the
    seed is in `info["episode_seed"]`). Each task's public evaluation seeds,
    `bbbench.spec(id).eval_seeds`, lie at or above 2**31.

    ## Episode End

    - Termination: the torso tilts more than 1 rad (57 degrees) from vertical (a fall).
    - Truncation: 1500 steps (15 s at 0.01 s per step), by gymnasium's `TimeLimit`.

    ## Arguments

    ```python
    import gymnasium as gym
    import bbbench

    env = gym.make("bbbench/FlatBalance-v1", action_mode="discrete", render_mode=None)
    env = gym.make("bbbench/Slopes-v2", difficulty=0.5, height_scan=True)
    ```

    - `action_mode`: `"discrete"` (the default) or `"continuous"`.
    - `render_mode`: `None`, `"rgb_array"` (320 x 240 frames from pybullet's
      TinyRenderer, headless, a camera that follows the bot) or `"human"`
      (pybullet's GUI window, real time).
    - `difficulty` (terrain tasks only): a number in [0, 1]; higher hills and
      obstacles. The default is the task's (0.3 for -v0; 0.9, 0.5 and 0.9 for
      Bumps-, Obstacles- and Slopes-v1 and -v2), and `env.spec` records it.
    - `height_scan`: False (default) or True, the ground heights ahead of the
      bot appended to the observation (see Height Scan above).
    - Perturbations (`bbbench.tasks.perturbations`), set at every reset, one
      keyword per axis. Given at its default, a perturbation makes the same task;
      otherwise `env.spec` records it and the fingerprint changes. The standard
      grid is what `bbbench sweep` and the board's robustness profile play.

    | keyword | unit | default | accepted | standard grid |
    |---|---|---|---|---|
    | `payload_mass` | kg on the torso | 0 | [0, 10] | 0, 1, 2, 3, 4 |
    | `com_offset` | m, centre of mass forward | 0 | [-0.2, 0.2] | -0.05, -0.025, 0, 0.025, 0.05 |
    | `friction` | times the ground's friction | 1 | (0, 10] | 0.2, 0.3, 0.5, 1, 1.5 |
    | `motor_strength` | times the servos' torque limit | 1 | (0, 10] | 0.1, 0.2, 0.5, 0.8, 1.2 |
    | `action_delay` | control steps of 10 ms | 0 | [0, 100] | 0, 1, 2, 3, 5 |
    | `sensor_noise` | times the sensors' noise | 0 or 1 | [0, 10] | 0, 0.5, 1, 2, 3 |
    | `push` | N s every 2-4 s | 0 | [0, 10] | 0, 0.25, 0.5, 0.75, 1 |

    - `payload_mass`: up to four times the 1 kg bot: over 0-1 kg no policy measured lost
      score; PPO falls from 2 kg on, PD from 8.
    - `com_offset`: legged_gym's and Isaac Lab's ±5 cm; at 2.5 cm PD keeps a quarter of its
      score.
    - `friction`: legged_gym's 0.1-2 about the 0.8 grip as built; below 0.5 the wheels slip.
    - `motor_strength`: down to a tenth: over 0.5-1.2 no policy measured lost score; PPO
      falls at 0.2, PD and LQR at 0.1.
    - `action_delay`: the real-world RL suite's 3-9 steps; PPO falls from 2 on, PD from 15.
    - `sensor_noise`: 1 is the tutorial's noise (NoisySensors', and on perfect sensors the
      same), 3 about the real-world RL suite's largest.
    - `push`: 1 N s changes the 1 kg bot's speed by about 1 m/s; at 2 N s every policy
      falls.

    The pybullet world is created on the first `reset()`; a pickled copy of the
    env carries no world and builds its own on its next `reset()`.

    ## Version History

    Each task's own class, made from its row of the suite, documents it
    (`help(env.unwrapped)`, or `bbbench list TASK`): `bbbench.envs.task_envs.FlatBalanceEnv`,
    `VelocityTrackingEnv`, `NoisySensorsEnv`, `BumpsEnv`, `ObstaclesEnv`, `SlopesEnv`,
    `PushRecoveryEnv`.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 100}

    def __init__(
        self,
        task: str | TaskSpec = "bbbench/FlatBalance-v1",
        action_mode: str | None = None,
        render_mode: str | None = None,
        difficulty: float | None = None,
        height_scan: bool | None = None,
        **unknown: Any,
    ) -> None:
        task = task if isinstance(task, TaskSpec) else spec(task)
        action_mode = action_mode or task.robot_model.default_action_mode
        task = requested_task(
            task,
            unknown,
            {"height_scan": height_scan, "difficulty": difficulty},
            action_mode,
            render_mode,
            self.metadata["render_modes"],
        )
        self.task = task
        self.action_mode = action_mode
        self.render_mode = render_mode
        self._human = render_mode == "human"
        self.action_space = task.robot_model.action_space(action_mode)
        self.metadata = {**self.metadata, "render_fps": round(1.0 / task.control_dt)}
        self._scene = scene = Scene(task, action_mode, gui=self._human)
        scenario = scene.scenario
        self.observation_space = scenario.observation_space()
        self.metrics = scenario.metrics  # per-episode metrics: info keys, averaged per step
        # The task's rules, bound once: the step's hot path calls them.
        self._observe, self._outcome = scenario.observe, scenario.outcome
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
        commands, targets = [scene.bots[0].wheel_command], [scene.target(0)]
        observation = self._observe(scene, states, commands, targets, 0)[0]
        if self._human:
            self._render_human()
        return observation, {"episode_seed": episode_seed}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        scene = self._scene
        command, state, target = scene.step_one(action)
        states, targets = (state,), (target,)
        outcome = self._outcome(_AGENT, states, targets, 0)
        if self._human:
            self._render_human()
        observation = self._observe(scene, states, (command,), targets, scene.steps)[0]
        return observation, outcome.rewards[0], outcome.over, False, outcome.infos[0]

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
