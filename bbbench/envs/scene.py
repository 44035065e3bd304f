"""`Scene`: one task's episode, the part both env APIs share.

A scene owns the physics: the pybullet `World`, the task's ground, its bots (one, or a
`Group`'s) and what the episode's seed drew (`scene.episode`: targets, sensor errors,
heightmap, starting poses). It resets from a seed, applies actions to the bots, steps
the world, and reads the bots. The task's rules are its scenario's
(`scene.scenario`, a `bbbench.tasks.scenarios.Scenario`): the scene asks it for its
extra bodies when it builds the world and for the starts when it resets.
`BalanceEnv` (Gymnasium) and `MultiBalanceEnv` (PettingZoo) are API layers over the
two: they hand observations, outcomes and ended bots to the scenario and turn what it
gives into the dicts their API wants.

Also here, written once for both envs: the keyword checks of their
constructors (`requested_task`) and the start of their `render()`.
"""

from __future__ import annotations

import difflib
from typing import Any

from gymnasium import logger

from bbbench.envs.episode import EpisodeDraw
from bbbench.robots import Body, BotState
from bbbench.sim import World
from bbbench.tasks.perturbations import PERTURBATIONS, refusal
from bbbench.tasks.scenarios import Scenario
from bbbench.tasks.sensors import PerfectSensors
from bbbench.tasks.spec import TaskSpec, seed_streams
from bbbench.terrain import load_ground

# m: where a bot taken out of the episode is set aside, far beyond anything an episode
# reaches; bot i at (SET_ASIDE_X + 10 i, 0, 10).
SET_ASIDE_X = 1000.0
_NEVER = -1  # the step of the next push when there is none: `steps` never equals it


def _sensed(reading: tuple, error: tuple) -> tuple[float, float, float]:
    """A (pitch, pitch rate, wheel speed) reading as sensors with that step's `error` give it."""
    return (reading[0] + error[0], reading[1] + error[1], reading[2] + error[2])


class Scene:
    """A task's world, ground and bots, and the episode being played in it.

    Args:
        task: the spec; a `Group` task has `task.group.n_bots` bots, any other one.
        action_mode: how `act` reads actions, one of the task's robot's action modes
            ("discrete" or "continuous" for the two-wheel bot: `bbbench.robots.twowheel`);
            None, the robot's first.
        gui: open pybullet's GUI window (the single-bot env's human render mode).

    The world is built on the first `reset()`; a pickled scene carries no world
    and builds its own on its next `reset()`. Bot i is `bots[i]`; `live` lists
    the bots still in the episode (all, until `take_out`).
    """

    def __init__(self, task: TaskSpec, action_mode: str | None = None, gui: bool = False) -> None:
        self.task = task
        self.robot = task.robot_model
        self.scenario = scenario = task.scenario_class(task)
        self.n_bots = scenario.n_bots
        self.action_mode = action_mode = action_mode or task.default_action_mode
        task.check_action_mode(action_mode)
        self.decode_action = self.robot.action_decoder(action_mode)
        # Each bot decodes its action with its own robot's decoder (on a mixed team, each
        # robot's; else the one robot's for every bot).
        self._decoders = [model.action_decoder(action_mode) for model in scenario.roster]
        # The channel's messages (`bbbench.tasks.channel`): what each bot sent with its
        # last action (zeros after reset), and the function that parts an action.
        self.channel = channel = task.channel
        self.sent: list[tuple[float, ...]] = []
        self._split = (
            None if channel is None else channel.splitter(self.robot.action_space(action_mode))
        )
        self.world = World(time_step=task.control_dt, substeps=task.physics_substeps, gui=gui)
        self.steps = 0  # world steps since the last reset
        self.limit = task.max_episode_steps  # the time limit: `truncated` at this many steps
        self.live: list[int] = []  # indices of the bots still in the episode, in order
        self.live_bots: list[Body] = []  # and those bots
        self._clear()
        self._delay = task.sensors.delay_steps
        # Decided by the task, not per step: perfect, undelayed sensors read the true state.
        self.perfect_sensors = (
            isinstance(task.sensors, PerfectSensors)
            and not self._delay
            and not any(change.observed for change in task.perturbations)
        )
        # And the shared five values alone, without the height scan: the observation is
        # built straight from the true state (the single-bot hot path).
        self.true_five_only = (
            self.perfect_sensors and not task.height_scan and self.robot.observes_shared_only
        )
        # Called before every multi-bot world step only by scenarios that couple bots.
        overridden = type(scenario).before_step is not Scenario.before_step
        self._before_step = scenario.before_step if overridden else None

    @property
    def truncated(self) -> bool:
        """Whether the episode has reached its time limit (`max_episode_steps` steps): the
        one place truncation is decided. Both envs return it as `truncated`, and the play
        loops end an episode on it."""
        return self.steps >= self.limit

    def _clear(self) -> None:
        """Forget the world's bodies (closed, or never built: a new or unpickled scene)."""
        self._pushes: dict[int, list[tuple[int, float]]] = {}  # step: [(bot, N s)]
        self._next_push = _NEVER  # the first step in `_pushes`
        self._ground = None
        self._bots: tuple[Body, ...] = ()
        self._first: Body | None = None  # bots[0], for the single-bot hot path
        self._world_step = None
        self._episode: EpisodeDraw | None = None
        self._follow = None
        self.live, self.live_bots = [], []

    # -- read-only views ------------------------------------------------------

    @property
    def built(self) -> bool:
        """Whether the world holds the ground and bots (after a `reset()`)."""
        return bool(self._bots)

    @property
    def ground(self):
        """The ground in the world (`BulletPlane` or `BulletHeightfield`); None before reset."""
        return self._ground

    @property
    def bots(self) -> tuple[Body, ...]:
        """Every bot of the scene, in order (empty before the first reset)."""
        return self._bots

    @property
    def episode(self) -> EpisodeDraw | None:
        """What the current episode's seed drew; None before the first reset."""
        return self._episode

    # -- the episode ----------------------------------------------------------

    def reset(self, seed: int) -> list[BotState]:
        """Start episode `seed`: draw its terrain, targets, sensor errors and starts, put
        every bot at rest at its start, and return the bots' states."""
        if any(bot.is_set_aside for bot in self._bots):
            # Taking a bot out and back moves its colliders in bullet's lists, and so the
            # order the solver meets contacts in: 1 of 8 PD episodes of MultiBumps-v1
            # played in a row differed from the same seed in a fresh world. Re-adding
            # the colliders in their first order is not enough (the broadphase keeps a
            # trace): a fresh world it is (tests/test_determinism.py).
            self.world.clear()
            self._clear()
        if not self._bots:
            self._build()
        task, n = self.task, self.n_bots
        streams = seed_streams(seed)
        ground = self._ground
        ground.reset(streams.terrain)
        poses, pitches = self.scenario.starts(streams.start)
        rows = self.scenario.targets(streams.command)
        # Each bot draws its own sensor errors, in order (a group's first draws one bot's).
        limit = task.max_episode_steps
        self._bot_errors = [task.sensors.episode_errors(streams.sensors, limit) for _ in range(n)]
        self._targets = rows[0]  # floats, for the hot path
        # [bot][step], for several bots (read as they are: a transposed copy of 1,501
        # lists costs a reset more than the rest of it, in a training's large heap)
        self._target_rows = rows if n > 1 else None
        self._pushes, self._next_push = {}, _NEVER
        for change in task.perturbations:  # the one seam: each sets its values again
            change.apply(self, streams.perturbation)
        pushes = tuple(
            (step, bot, impulse)
            for step in sorted(self._pushes)
            for bot, impulse in self._pushes[step]
        )
        first = self._bot_errors[0]
        errors = self._bot_errors if n > 1 and first is not None else first
        self._episode = EpisodeDraw(
            seed, rows, errors, getattr(ground, "heightmap", None), poses, pitches, pushes
        )
        # Bullet keeps contact points from step to step and warm-starts its solver from
        # them: drop the last episode's, with every bot clear of everything at once
        # (tests/test_determinism.py: an episode does not depend on the ones before it).
        for bot in self._bots:
            bot.move_clear()
        self.scenario.move_clear(self)  # and the scenario's own bodies
        self.world.detect_collisions()
        for bot, ((x, y), yaw), pitch in zip(self._bots, poses, pitches, strict=True):
            bot.reset(
                pitch=float(pitch),
                yaw=yaw,
                xy=(x, y),
                ground_height=ground.spawn_height(x, y),
                drop_contacts=False,
            )
        self.scenario.place(self, streams.start)
        self.steps = 0
        self.live = list(range(n))
        self.live_bots = list(self._bots)
        if self.channel is not None:
            self.sent = self.channel.silence(n)
        states = [bot.read() for bot in self._bots]
        first = states[0]  # what a delayed sensor reports at the first step
        self._last_reading = (first.pitch, first.pitch_rate, first.wheel_speed)
        return states

    def act_live(self, actions) -> None:
        """Apply `actions[k]` to the k-th live bot; `ActionError` names the k of a bad one."""
        split = self._split
        if split is not None:  # each bot's action parted: the robot's, and its message
            try:
                parted = [split(action) for action in actions]
            except ValueError:
                for k, action in enumerate(actions):  # which one, for the error
                    try:
                        split(action)
                    except ValueError as error:
                        raise ActionError(k, error) from None
                raise
            sent, actions = self.sent, []
            for i, (action, message) in zip(self.live, parted, strict=True):
                sent[i] = message
                actions.append(action)
        decoders, live = self._decoders, self.live
        for k, (bot, action) in enumerate(zip(self.live_bots, actions, strict=True)):
            try:
                bot.act(decoders[live[k]](action))
            except ValueError as error:
                raise ActionError(k, error) from None

    def step_one(self, action: Any) -> tuple[float, BotState, float]:
        """A single-bot task's step: apply `action` to the bot, step the world, read the
        bot; return its wheel command, its state and its target velocity now.

        One call for the whole hot path of `BalanceEnv.step` (benchmarks/bench_core.py).
        """
        bot = self._first
        if bot is None:
            raise RuntimeError(
                f"{self.task.id}: call reset() before step() (a new or unpickled env has no world)"
            )
        command = bot.act(self.decode_action(action))
        if self.steps == self._next_push:
            self._push()
        self._world_step()
        self.steps = steps = self.steps + 1
        state = bot.read()
        if self._follow is not None:
            self._follow(state.axle[0])
        targets = self._targets
        return command, state, targets[steps] if steps < len(targets) else targets[-1]

    def advance_live(self) -> list[BotState]:
        """Step the world once and read the live bots, in order."""
        if self._before_step is not None:
            self._before_step(self)
        if self.steps == self._next_push:
            self._push()
        self._world_step()
        self.steps += 1
        return [bot.read() for bot in self.live_bots]

    def target(self, step: int) -> float:
        """The first bot's target velocity (m/s) at `step` (the last one past the limit)."""
        targets = self._targets
        return targets[step] if step < len(targets) else targets[-1]

    def live_targets(self, step: int) -> list[float]:
        """The live bots' target velocities (m/s) at `step`, in order."""
        rows = self._target_rows
        if rows is None:  # one bot
            return [self.target(step)] if self.live else []
        step = min(step, len(rows[0]) - 1)
        return [rows[i][step] for i in self.live]

    def reading(self, state: BotState, step: int) -> tuple[float, float, float]:
        """The first bot's pitch, pitch rate and wheel speed as the task's sensors read
        them at `step`: delayed, biased, noisy."""
        reading = (state.pitch, state.pitch_rate, state.wheel_speed)
        if self.perfect_sensors:
            return reading
        if self._delay:
            reading, self._last_reading = self._last_reading, reading
        errors = self._bot_errors[0]
        if errors is not None:
            reading = _sensed(reading, errors[min(step, len(errors) - 1)])
        return reading

    def live_readings(self, states: list[BotState], step: int) -> list[tuple] | None:
        """The live bots' pitch, pitch rate and wheel speed as the task's sensors read them
        at `step`, each with its own errors (a group's are never delayed); None for
        perfect sensors (read the states)."""
        if self.perfect_sensors:
            return None
        rows = self._bot_errors
        step = min(step, len(rows[0]) - 1)
        return [
            _sensed((s.pitch, s.pitch_rate, s.wheel_speed), rows[i][step])
            for s, i in zip(states, self.live, strict=True)
        ]

    # -- what perturbations set (`bbbench.tasks.perturbations`) ---------------------

    @property
    def sensor_errors(self) -> list[tuple[float, float, float]] | None:
        """This episode's (pitch, pitch rate, wheel speed) sensor error of the first bot at
        each step, bias included (None: perfect sensors); a perturbation may replace it at
        reset."""
        return self._bot_errors[0]

    @sensor_errors.setter
    def sensor_errors(self, errors: list[tuple[float, float, float]] | None) -> None:
        self._bot_errors[0] = errors

    def schedule_push(self, step: int, bot: int, impulse: float) -> None:
        """Push bot `bot` with `impulse` N s along its heading just before world step
        `step` of this episode (a bot out of the episode by then is not pushed)."""
        self._pushes.setdefault(step, []).append((bot, impulse))
        self._next_push = min(self._pushes)

    def _push(self) -> None:
        pushes = self._pushes.pop(self.steps)
        live = set(self.live)
        for index, impulse in pushes:
            if index in live:
                self._bots[index].push(impulse, self.task.control_dt)
        self._next_push = min(self._pushes, default=_NEVER)

    def take_out(self, indices) -> None:
        """Take bots out of the episode: they collide with nothing and wait far away
        (set aside, not removed: body ids, and so the world's pair order, stay)."""
        gone = set(indices)
        for i in indices:
            self._bots[i].set_aside((SET_ASIDE_X + 10.0 * i, 0.0, 10.0))
        self.live_bots = [
            bot for i, bot in zip(self.live, self.live_bots, strict=True) if i not in gone
        ]
        self.live = [i for i in self.live if i not in gone]

    def close(self) -> None:
        self.world.close()
        self._clear()

    # -- internals ------------------------------------------------------------

    def _build(self) -> None:
        client = self.world.client
        self._ground = load_ground(client, self.task.terrain)
        self._bots = tuple(model.body(client) for model in self.scenario.roster)
        self._first = self._bots[0]
        self.scenario.build(client, self._bots)
        self._world_step = self.world.step
        # Terrain with no side edge moves with its one bot (`BulletHeightfield.follow`).
        if self._ground.period is not None:
            if self.n_bots != 1:
                raise ValueError(f"{self.task.id}: a moving ground follows a single bot")
            self._follow = self._ground.follow

    def __getstate__(self) -> dict[str, Any]:
        # The world pickles as a description; bodies belong to the old connection.
        state = self.__dict__.copy()
        state.update(_ground=None, _bots=(), _first=None, _world_step=None, _episode=None)
        state.update(_follow=None, live=[], live_bots=[])
        state.update(_pushes={}, _next_push=_NEVER)
        for key in ("_targets", "_target_rows", "_bot_errors", "_last_reading"):
            state.pop(key, None)
        return state


class ActionError(ValueError):
    """An action a bot's action space does not hold; `index` is its place among the live bots."""

    def __init__(self, index: int, error: ValueError) -> None:
        super().__init__(str(error))
        self.index = index


# Each option an env takes, and the TaskSpec method that derives the task it asks for.
_DERIVE = {
    "n_bots": "with_n_bots",
    "difficulty": "with_difficulty",
    "max_episode_steps": "with_time_limit",
    "height_scan": "with_height_scan",
}
CHANNEL_OPTIONS = ("message_width", "comm_range", "mute_messages")


def requested_task(
    task: TaskSpec,
    unknown: dict[str, Any],
    options: dict[str, Any],
    action_mode: str,
    render_mode: str | None,
    render_modes: list[str],
    several_bots: bool = False,
) -> TaskSpec:
    """The task an env's keyword arguments ask for, or the error that says what is wrong.

    `options` maps each keyword the env takes beyond action_mode and render_mode to the
    value given (None: not given): `difficulty`, `height_scan`, `n_bots`,
    `max_episode_steps`; each given one derives the spec (`TaskSpec.with_...`). On a
    task with a channel, `unknown` may hold `message_width`, `comm_range` and
    `mute_messages` (`TaskSpec.with_channel`).
    `unknown` holds the keywords the env does not take. `several_bots`: the env is the
    multi-bot one, which plays `Group` tasks.
    """
    if several_bots and task.group is None:
        raise ValueError(
            f"{task.id} is a single-bot task: make it with gymnasium.make or bbbench.make"
        )
    terrain = task.difficulty is not None
    accepted = [f"action_mode={task.action_modes}", f"render_mode={(None, *render_modes)}"]
    scans = task.scenario_class.scans_ground
    accepted += [
        name
        for name in options
        if (name != "difficulty" or terrain) and (name != "height_scan" or scans)
    ]
    if task.channel is not None:
        accepted += CHANNEL_OPTIONS
    accepted += [keyword for keyword in PERTURBATIONS if refusal(keyword, task) is None]
    perturbations = {k: unknown.pop(k) for k in list(unknown) if k in PERTURBATIONS}
    talk = {k: unknown.pop(k) for k in CHANNEL_OPTIONS if k in unknown and task.channel}
    wrong = sorted(unknown)
    if options.get("difficulty") is not None and not terrain:
        wrong.append("difficulty")
    if wrong:
        names = ["action_mode", "render_mode", *accepted[2:]]
        close = [m for w in wrong for m in difflib.get_close_matches(w, names, n=1, cutoff=0.7)]
        raise TypeError(
            f"unknown keyword argument(s) {wrong} for {task.id}"
            + (f" (did you mean {', '.join(close)}?)" if close else "")
            + f": accepted keyword arguments are {', '.join(accepted)}"
            + (" (difficulty: a number in [0, 1])" if terrain else "")
        )
    for name, value in options.items():
        if value is not None:
            task = getattr(task, _DERIVE[name])(value)
    if talk:
        task = task.with_channel(**talk)
    for keyword, value in perturbations.items():
        task = task.with_perturbation(PERTURBATIONS[keyword](value))
    task.check_action_mode(action_mode)
    if render_mode is not None and render_mode not in render_modes:
        raise ValueError(f"render_mode must be None or one of {render_modes}, got {render_mode!r}")
    refused = [refusal(keyword, task) for keyword in perturbations]
    if any(refused):
        raise ValueError(next(reason for reason in refused if reason))
    return task


def render_ready(env) -> bool:
    """The start of both envs' `render()`: False (with gymnasium's warning) without a
    render mode; a clear error before the first reset; else True."""
    if env.render_mode is None:
        logger.warn(
            "render() was called without a render_mode; make the env with "
            f"render_mode={' or '.join(repr(mode) for mode in env.metadata['render_modes'])}."
        )
        return False
    if not env.scene.built:
        raise RuntimeError(f"{env.task.id}: call reset() before render()")
    return True
