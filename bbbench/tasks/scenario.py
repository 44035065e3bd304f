"""`Scenario`: a task's rules on one screen, beneath both env APIs.

dm_control's `Task` (`initialize_episode`, `get_observation`, `get_reward`) and VMAS's
`Scenario` (`make_world`, `reset_world_at`, `observation`, `reward`, `done`, `info`)
keep what makes a task itself in one class; bbbench's does the same. A task spec names
its scenario (`TaskSpec.scenario`) as it names its robot, and each env's `Scene` makes
one instance of it for its world. The scene keeps the physics (world, ground, bots,
stepping, reading); the scenario owns:

| what it owns                        | where                                              |
|-------------------------------------|----------------------------------------------------|
| extra bodies and constraints        | `build(client, bots)`                              |
| the starting poses                  | `starts(rng)`; its bodies: `move_clear`, `place`   |
| the observation's fields and values | `layout` (its space and docs' tables), `observe`   |
| each step's outcome                 | `outcome`: an `Outcome` (rewards, falls, its end)  |
| the per-episode metrics             | `metrics`: info keys averaged per bot-step         |
| what becomes of a bot that has ended | `leave(scene, indices)`                           |
| where `payload_mass` goes            | `set_payload(scene, kg)`: each torso by default    |
| what a frame shows beyond the bodies | `draw(scene)` (a tether), before each frame        |

Both envs, and every tool that plays them, read the scenario through one step protocol,
`observe_and_score`: after every reset and every step, `observe`, then `outcome` (the
order in one place, as VMAS's `env_*` methods keep it): the live bots' rows, and an
`Outcome` that says each bot's reward,
which bots fell, whether the episode is over for all of them, and why. The env maps
the outcome to its API (Gymnasium's `terminated`, PettingZoo's dicts) and decides
nothing itself. A single-bot task is the case of one bot.

A scenario is made per scene (`Scenario(task)`): it may keep what it built in the
world (a beam's body id, its constraints, the world's client) on itself; a pickled
copy drops the client, and its first reset builds the world and calls `build` again.
docs/architecture.md, "How to add a scenario", walks through writing one.
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Sequence
from typing import Any, ClassVar, NamedTuple, final

import numpy as np
import pybullet
from gymnasium import spaces
from pybullet_utils.bullet_client import BulletClient

from bbbench.robots.layout import ObservationField, box
from bbbench.tasks.commands import PiecewiseConstantTwist
from bbbench.tasks.group import MIN_BOTS
from bbbench.tasks.reward import TwistReward
from bbbench.tasks.sensors import PerfectSensors

# The spec imports the scenarios, not the other way round: a task is typed `Task` here.
Task = Any  # a `bbbench.tasks.spec.TaskSpec`

Pose = tuple[tuple[float, float], float]  # (x, y) m and yaw rad; yaw 0 faces +y


@dataclasses.dataclass(slots=True)  # not frozen: made at every step, and frozen costs 3x
class Outcome:
    """What a reset or a step came to, for the live bots in their order.

    `rewards` and `fell`: each bot's reward and whether it fell (at a reset, what the
    starting states would earn, and no fall). `over`: the episode is over for every
    bot, fallen or not (a team's end). `cause`: why bots' episodes end at this step,
    naming them as the agents are named ("bot_1 fell", "bot_0, bot_2 fell", "a tether
    broke", "bot_1 fell; a tether broke"), or "" if none does; the time limit is the
    env's, not the scenario's. `infos`: each bot's info, the same keys at every step.
    """

    rewards: Sequence[float]
    fell: Sequence[bool]
    over: bool
    cause: str
    infos: Sequence[dict[str, Any]]


def fell_cause(agents: list[str], fell: list[bool]) -> str:
    """The cause that names the bots that fell: "bot_1 fell", "bot_0, bot_2 fell", or ""
    if none did."""
    if True not in fell:  # most steps: no fall
        return ""
    fallen = [agent for agent, down in zip(agents, fell, strict=True) if down]
    return f"{', '.join(fallen)} fell" if fallen else ""


class Slots(NamedTuple):
    """How a multi-bot observation reads, for models that encode neighbours: the bot's
    `own` values, then `count` slots of `width` values, one per neighbour; `presence`,
    the index in a slot of its presence bit (None: every slot is a bot)."""

    own: int
    count: int
    width: int
    presence: int | None

    def presence_columns(self) -> tuple[int, ...]:
        """Where each slot's presence bit sits in the observation (none without one)."""
        if self.presence is None:
            return ()
        return tuple(self.own + k * self.width + self.presence for k in range(self.count))


# Every scenario, by the name a task spec gives (`TaskSpec.scenario`), in the suite's
# order: each module of `bbbench.tasks.scenarios` registers its own.
SCENARIOS: dict[str, type[Scenario]] = {}


# What a steering bot can head for (`Scenario.heads_for`): a guide of the steering
# controllers (`bbbench.policies.controllers.steer.GUIDES`) follows each.
HEADINGS = ("the command", "the goal")


def register_scenario(cls: type[Scenario]) -> type[Scenario]:
    """Register the scenario `cls` under its `name`; `ValueError` if the name is taken or
    it heads for what no steering guide follows."""
    if cls.name in SCENARIOS:
        raise ValueError(f"a scenario is already called {cls.name!r}")
    if cls.observe_and_score is not Scenario.observe_and_score:
        raise ValueError(
            f"scenario {cls.name!r} overrides observe_and_score, the step protocol both envs "
            "follow (observe, then outcome): write observe and outcome instead"
        )
    if cls.heads_for is not None and cls.heads_for not in HEADINGS:
        raise ValueError(
            f"scenario {cls.name!r}: heads_for is {cls.heads_for!r}; it is one of "
            f"{', '.join(map(repr, HEADINGS))}, or None where steering controllers do not play"
        )
    SCENARIOS[cls.name] = cls
    return cls


def scenario(name: str) -> type[Scenario]:
    """The scenario called `name` (`TaskSpec.scenario`), or a KeyError that lists them."""
    try:
        return SCENARIOS[name]
    except KeyError:
        raise KeyError(f"no scenario {name!r}: the scenarios are {', '.join(SCENARIOS)}") from None


class Scenario(abc.ABC):
    """What makes a task itself; each scenario is registered in `SCENARIOS` by `name`
    (`register_scenario`, in its module, before the rows that name it).

    Class attributes:
        name: what `TaskSpec.scenario` holds.
        summary: one line, for error messages and docs.
        multi_agent: played by `MultiBalanceEnv` (PettingZoo, needs the spec's `Group`),
            or by `BalanceEnv` (Gymnasium, one bot).
        robots: the robots it can play (`bbbench.robots.ROBOTS` names); None for any.
        mixes: it plays a mixed team (`TaskSpec.robots`): each bot's layout and spaces
            its own robot's (`layouts`).
        metrics: the names of the per-episode metrics: each is an `info` key of every
            agent's step, and an episode's value is its mean over the episode's
            bot-steps (`bbbench.evaluation.play`). The results document writes them in
            this order.
        team: the bots end together (coupled bots: multiwalker's `terminate_on_fall`);
            its `outcome` says when (`over`), and results record each episode's cause.
        perturbations: the env keywords of the perturbations
            (`bbbench.tasks.perturbations`) it takes; None for all.
        most_bots: the most bots it plays; None for as many as a `Group` holds.
        units: a perturbation's unit where the scenario applies it elsewhere than the
            perturbation says (BeamCarry's payload is the beam's).
        steers: its targets are (velocity, yaw rate) pairs (`PiecewiseConstantTwist`),
            scored by `TwistReward`; else forward velocities, scored by the others.
        senses: it observes its bots through the task's sensors (`scene.reading`; a
            group's `scene.live_readings`, each bot's own errors, never delayed); else
            through perfect sensors, and a task with others is refused.
        scans_ground: it observes the ground's heights ahead when the task asks
            (`height_scan=True`); else `height_scan` is refused.
        controller: the built-in policy that is its tasks' classical controller (the one
            learned methods are set against); None for its robot's (`Robot.controller`).
        reward_type: the reward class its tasks must score (its `outcome` calls that
            class's terms); None for any the other checks allow.
        heads_for: what a steering controller heads for on it, read from its observation:
            "the command" (the target twist) or "the goal" (its distance and bearing);
            None where the steering controllers do not play it.
    """

    name: ClassVar[str]
    summary: ClassVar[str]
    multi_agent: ClassVar[bool] = False
    robots: ClassVar[tuple[str, ...] | None] = None
    mixes: ClassVar[bool] = False
    metrics: ClassVar[tuple[str, ...]] = ("velocity_error",)
    team: ClassVar[bool] = False
    perturbations: ClassVar[tuple[str, ...] | None] = None
    most_bots: ClassVar[int | None] = None
    units: ClassVar[dict[str, str]] = {}
    steers: ClassVar[bool] = False
    scans_ground: ClassVar[bool] = False
    senses: ClassVar[bool] = False
    controller: ClassVar[str | None] = None
    heads_for: ClassVar[str | None] = None
    reward_type: ClassVar[type | None] = None

    def __init__(self, task: Task) -> None:
        self.task = task
        self.robot = task.robot_model
        # Each bot's robot, in order: `robot` for every bot but on a mixed team.
        self.roster = task.bot_robots
        self.reward = task.reward

    @classmethod
    def refusal(cls, task: Task) -> str | None:
        """Why the scenario cannot play `task` (its robot, its group); None if it can."""
        if task.robots and not cls.mixes:
            return f"{task.id}: the {cls.name!r} scenario plays one robot, not a mixed team"
        for name in task.robots or (task.robot,):
            if cls.robots is not None and name not in cls.robots:
                return (
                    f"{task.id}: the {cls.name!r} scenario cannot play the {name} robot: "
                    f"it plays {', '.join(cls.robots)}"
                )
        if cls.multi_agent and task.group is None:
            return f"{task.id}: the {cls.name!r} scenario needs several bots (a Group)"
        if not cls.multi_agent and task.group is not None:
            return f"{task.id}: the {cls.name!r} scenario plays one bot, not a Group"
        if cls.steers != isinstance(task.command, PiecewiseConstantTwist):
            wants = (
                "a velocity and a yaw rate (PiecewiseConstantTwist)"
                if cls.steers
                else ("a forward velocity")
            )
            return (
                f"{task.id}: the {cls.name!r} scenario commands {wants}, got "
                f"{type(task.command).__name__}"
            )
        if cls.steers != isinstance(task.reward, TwistReward):
            wants = "TwistReward" if cls.steers else "a velocity's reward, not TwistReward"
            return f"{task.id}: the {cls.name!r} scenario scores {wants}"
        if cls.reward_type is not None and not isinstance(task.reward, cls.reward_type):
            return f"{task.id}: the {cls.name!r} scenario scores {cls.reward_type.__name__}"
        sensors = task.sensors
        if not cls.senses and not isinstance(sensors, PerfectSensors):
            return f"{task.id}: the {cls.name!r} scenario observes through perfect sensors only"
        if cls.multi_agent and sensors.delay_steps:
            return (
                f"{task.id}: a group's sensors are not delayed: give delay_steps=0, got "
                f"{sensors.delay_steps}"
            )
        if cls.most_bots is not None and task.group.n_bots > cls.most_bots:
            return (
                f"{task.id}: n_bots must be from {MIN_BOTS} to {cls.most_bots} for the "
                f"{cls.name!r} scenario, got {task.group.n_bots}"
            )
        return None

    @property
    def n_bots(self) -> int:
        return self.task.group.n_bots if self.task.group is not None else 1

    # -- the world --------------------------------------------------------------

    def build(self, client: Any, bots: tuple[Any, ...]) -> None:
        """Add the scenario's own bodies and constraints to a new world that holds the
        ground and `bots` (none by default). Called once per world."""

    def set_payload(self, scene: Any, kg: float) -> None:
        """`payload_mass`: carry `kg` more. By default each bot at its torso's centre of
        mass; a scenario that carries something (a beam) may put it there instead."""
        for bot in scene.bots:
            bot.set_payload(kg)

    # -- the episode's start ----------------------------------------------------

    @abc.abstractmethod
    def starts(self, rng: np.random.Generator) -> tuple[list[Pose], list[float]]:
        """Each bot's starting pose and initial lean (rad), drawn from the episode's start
        stream."""

    def move_clear(self, scene: Any) -> None:
        """At reset, before the bots are placed: move the scenario's own bodies clear of
        everything (as each bot's `move_clear`), so that the scene's one collision pass
        drops their contact points of the last episode (nothing by default)."""

    def place(self, scene: Any, rng: np.random.Generator) -> None:
        """After the bots stand at their starts: put the scenario's own bodies in place
        for the episode (nothing by default). `rng` is the start stream, past `starts`."""

    def targets(self, rng: np.random.Generator) -> list[list[float]]:
        """Each bot's target velocity (m/s) after reset and after each step, drawn from the
        episode's command stream: by default a schedule of the task's command per bot."""
        task = self.task
        return [
            task.command.targets(rng, task.max_episode_steps, task.control_dt)
            for _ in range(self.n_bots)
        ]

    # -- stepping -------------------------------------------------------------------

    def before_step(self, scene: Any) -> None:
        """Just before every world step of a multi-bot episode: apply the forces the
        scenario's own couplings exert (bullet clears external forces after each step).
        Nothing by default, and then the scene does not call it."""

    def draw(self, scene: Any) -> None:
        """Before a frame is rendered: show what the camera would not see of the
        scenario (a tether is a force, not a body). Nothing by default. Whatever it adds
        must not collide or weigh: a rendered episode plays as an unrendered one."""

    # -- observations -------------------------------------------------------------

    # Every field of one agent's observation, in order: set by `__init__`. The space is
    # made from it, and the docs' observation tables are printed from it.
    layout: tuple[ObservationField, ...]

    def observation_space(self) -> spaces.Box:
        """One agent's observation space, made from `layout` (the same object every call).

        `observe` runs once after every reset and every step, before `outcome`: a
        scenario reads its own bodies there, once a step, and keeps what `outcome` and
        `before_step` need."""
        space = self.__dict__.get("_space")
        if space is None:
            space = self.__dict__["_space"] = box(self.layout)
        return space

    def bot_layout(self, bot: int) -> tuple[ObservationField, ...]:
        """Bot `bot`'s fields: `layout`, but on a mixed team, where each bot observes in
        its own robot's layout (a `mixes` scenario writes this)."""
        return self.layout

    def bot_observation_space(self, bot: int) -> spaces.Box:
        """Bot `bot`'s observation space, from `bot_layout` (one object per layout)."""
        layout = self.bot_layout(bot)
        if layout is self.layout:
            return self.observation_space()
        spaces_ = self.__dict__.setdefault("_spaces", {})
        if layout not in spaces_:
            spaces_[layout] = box(layout)
        return spaces_[layout]

    @abc.abstractmethod
    def observe(
        self,
        scene: Any,
        states: list[Any],
        commands: list[float],
        targets: list[float],
        step: int,
    ) -> np.ndarray | list[np.ndarray]:
        """The live bots' observations, one row each (float32, `observation_space()`'s
        width: an array of rows, or a list of them), from their `states`, wheel
        `commands` and `targets`, at `step` of the episode (0 after reset); `scene`
        gives the task's sensors and ground."""

    @abc.abstractmethod
    def outcome(
        self, agents: list[str], states: list[Any], targets: list[float], seed: int
    ) -> Outcome:
        """The `Outcome` of the live bots (`agents`, their `states` and `targets`) in the
        episode of `seed`, after a reset or a step."""

    @final
    def observe_and_score(
        self,
        scene: Any,
        agents: list[str],
        states: list[Any],
        commands: list[float],
        targets: list[float],
        seed: int,
    ) -> tuple[np.ndarray | list[np.ndarray], Outcome]:
        """The step protocol, written once (as VMAS's `env_*` methods): after every reset
        and every step, both envs call this, and it calls `observe`, then `outcome`, for
        the live bots at the scene's step. A scenario writes those two and never this
        (`register_scenario` refuses one that does)."""
        observations = self.observe(scene, states, commands, targets, scene.steps)
        return observations, self.outcome(agents, states, targets, seed)

    def slots(self) -> Slots | None:
        """How its observation lays out the neighbours (`Slots`); None for one bot."""
        return None

    def bot_slots(self, bot: int) -> Slots | None:
        """`slots` of bot `bot`'s observation (its own robot's, on a mixed team)."""
        return self.slots()

    # -- pickling ---------------------------------------------------------------------

    def __getstate__(self) -> dict[str, Any]:
        # A pickled scene carries no world (cloudpickle copies of an env must not share
        # one): the copy's first reset builds a new world, and `build` runs again there.
        return {k: v for k, v in self.__dict__.items() if not isinstance(v, BulletClient)}

    # -- what a bot leaves behind -------------------------------------------------------

    def leave(self, scene: Any, indices: list[int]) -> None:
        """Bots `indices` have ended their episodes (a fall, the time limit, the team's
        end): what becomes of their bodies. By default they stay where they are; never
        move a body a constraint holds."""


_OUT_OF_SIGHT = (0.0, 0.0, -5.0)  # where a disc waits before `place_disc` first puts it


def discs(client: Any, count: int, radius: float, colour: tuple[float, ...]) -> list[int]:
    """`count` flat discs for a scenario's `draw` to show on the ground (goals, a course,
    landmarks): bodies without mass or collision shape, which no physics step meets,
    out of sight until placed."""
    shape = client.createVisualShape(
        pybullet.GEOM_CYLINDER, radius=radius, length=0.01, rgbaColor=colour
    )
    return [client.createMultiBody(0.0, -1, shape, _OUT_OF_SIGHT) for _ in range(count)]


def place_disc(
    client: Any, body: int, x: float, y: float, ground: float = 0.0, colour=None
) -> None:
    """Lay a disc of `discs` on the ground at (x, y) (`ground`: its height there), in
    `colour` if given."""
    client.resetBasePositionAndOrientation(body, (x, y, ground + 0.005), (0.0, 0.0, 0.0, 1.0))
    if colour is not None:
        client.changeVisualShape(body, -1, rgbaColor=colour)
