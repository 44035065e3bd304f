"""`TaskSpec`: everything that defines one versioned task, frozen."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import operator
import re
from dataclasses import field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from gymnasium import spaces

from bbbench.parameters import parameters
from bbbench.robots import FALL_TILT, ROBOTS, Robot, robot
from bbbench.tasks.channel import Channel
from bbbench.tasks.commands import CommandSchedule, ConstantVelocity
from bbbench.tasks.group import MIN_BOTS, Group, team_robot
from bbbench.tasks.perturbations import PERTURBATIONS
from bbbench.tasks.reward import Reward, RewardWeights
from bbbench.tasks.scenario import SCENARIOS, Scenario
from bbbench.tasks.sensors import PerfectSensors, SensorModel
from bbbench.terrain import FlatGround, HeightfieldTerrain

# The train/validation/test split (Procgen's, applied to terrain and commands, with seeds
# to tune on that are neither): an episode is decided by one integer seed. reset()
# without a seed plays a training seed; every task's public evaluation seeds lie outside
# that range, and its public validation seeds outside both. Hyperparameters, gains,
# checkpoints and calibrations are chosen on training or validation seeds, never on the
# evaluation seeds the board scores.
TRAINING_SEEDS = range(2**31)
EVAL_SEEDS = tuple(range(2**31, 2**31 + 100))
VALIDATION_SEEDS = tuple(range(2**31 + 2**30, 2**31 + 2**30 + 100))
SEED_SPLITS = ("evaluation", "validation")  # `TaskSpec.seeds`, `bbbench eval --seeds`


class SeedStreams(NamedTuple):
    """Independent generators for the parts of one episode, all from its seed."""

    terrain: np.random.Generator
    command: np.random.Generator
    start: np.random.Generator
    sensors: np.random.Generator
    perturbation: np.random.Generator  # added later: the streams before it draw as they did


def seed_streams(episode_seed: int) -> SeedStreams:
    """The episode's generators: a harder terrain does not change the same seed's commands."""
    children = np.random.SeedSequence(episode_seed).spawn(len(SeedStreams._fields))
    return SeedStreams(*(np.random.default_rng(child) for child in children))


# Fields that document or score a task without changing its behaviour: editing
# them must not change the fingerprint.
_NOT_BEHAVIOUR_FIELDS = ("summary", "description", "version_history", "random_return")
# Options added after tasks were published (fields of the spec or of its components), with
# the value that means "as before": hashed only when set otherwise, so that adding an
# option moves no published fingerprint.
_OPTIONS_ADDED_LATER = {
    "height_scan": False,
    "lateral_period": None,
    "perturbations": (),
    "robot": "two-wheel",
    "coupling": None,
    "validation_seeds": VALIDATION_SEEDS,
    "channel": None,
    "robots": (),
}


def _published_options(value):
    """`value` (from `dataclasses.asdict`) without the later options at their defaults."""
    if isinstance(value, dict):
        return {
            key: _published_options(item)
            for key, item in value.items()
            if not (key in _OPTIONS_ADDED_LATER and item == _OPTIONS_ADDED_LATER[key])
        }
    if isinstance(value, list | tuple):
        return [_published_options(item) for item in value]
    return value


def _components(value) -> list[Any]:
    """Every component (frozen dataclass) in `value`, itself included, depth first in field
    order, but for the later options at their defaults (hashed as if they were not there)."""
    if isinstance(value, list | tuple):
        return [component for item in value for component in _components(item)]
    if not dataclasses.is_dataclass(value) or isinstance(value, type):
        return []
    found = [value]
    for field_ in dataclasses.fields(value):
        item, name = getattr(value, field_.name), field_.name
        if not (name in _OPTIONS_ADDED_LATER and item == _OPTIONS_ADDED_LATER[name]):
            found += _components(item)
    return found


def implied_scenario(group: Group | None) -> str:
    """The scenario of a spec that names none: the published tasks' ("crossing" for a
    group of bots, "solo" for one)."""
    return "solo" if group is None else "crossing"


_TASK_ID = re.compile(r"(?:(?P<namespace>[\w.-]+)/)?(?P<name>[\w.-]+?)-v(?P<version>\d+)")


def parse_task_id(task_id: str) -> tuple[str | None, str, int]:
    """('bbbench', 'Bumps', 0) for 'bbbench/Bumps-v0': namespace, name, version (one regex,
    as gymnasium parses its IDs)."""
    match = _TASK_ID.fullmatch(task_id)
    if match is None:
        raise ValueError(f"{task_id!r} is not a task ID of the form namespace/Name-vN")
    return match["namespace"], match["name"], int(match["version"])


@parameters
class TaskSpec:
    """One task of the suite. A task is a row of specs, not a class.

    Changing any field but `summary`, `description`, `version_history` and
    `random_return` (which is measured from the others) changes `fingerprint`, and so
    needs a new version of the task ID.
    """

    id: str
    summary: str  # one line: `bbbench list`, and the first line of the task's docstring
    # What the task adds to what every task shares (Markdown): its env's docstring
    # (`bbbench.envs.task_envs`) and `bbbench list TASK`.
    description: str = ""
    terrain: FlatGround | HeightfieldTerrain = field(default_factory=FlatGround)
    command: CommandSchedule = field(default_factory=ConstantVelocity)
    sensors: SensorModel = field(default_factory=PerfectSensors)
    reward: Reward = field(default_factory=RewardWeights)
    initial_pitch: float = 0.1  # rad: reset leans the bot by U(-initial_pitch, initial_pitch)
    control_dt: float = 0.01  # s per env step
    physics_substeps: int = 1  # pybullet sub-steps per env step
    max_episode_steps: int = 1500  # time limit (truncation)
    eval_seeds: tuple[int, ...] = EVAL_SEEDS
    # Seeds to make choices on (a recipe's hyperparameters, a controller's gains, a
    # checkpoint, a calibration), disjoint from the training and evaluation seeds.
    validation_seeds: tuple[int, ...] = VALIDATION_SEEDS
    group: Group | None = None  # several bots in one world (a PettingZoo task), or one
    # The observation ends with ground heights ahead of the bot (`robots/layout.py`).
    height_scan: bool = False
    # Reset-time changes of the robot or its world, each not at its default
    # (`bbbench.tasks.perturbations`), sorted by keyword.
    perturbations: tuple[Any, ...] = ()
    # The robot the task plays (`bbbench.robots.ROBOTS`): its body, actions and layout.
    robot: str = "two-wheel"
    # A mixed team's robots (`bbbench.robots.ROBOTS` names, `robot` first): bot i plays
    # robots[i % len(robots)]. Empty: every bot plays `robot`.
    robots: tuple[str, ...] = ()
    # The task's rules (`bbbench.tasks.scenario.SCENARIOS`): extra bodies, starts,
    # observation, outcome, metrics. None: the one its group implies, "crossing" for a
    # group and "solo" for one bot (the published tasks' scenarios, hashed as if absent).
    scenario: str | None = None
    # What couples a team's bots, a component of its scenario's module (`Beam`, `Tether`),
    # checked by the scenario (`Column.refusal`); None for none.
    coupling: Any = None
    # What the bots can say to each other (`bbbench.tasks.channel`): message values in
    # each action, the messages of the nearest senders in each observation; None: nothing.
    channel: Channel | None = None
    version_history: tuple[str, ...] = ("v0: initial release.",)
    # The random policy's mean return (per bot) over eval_seeds, in the robot's default
    # action mode (discrete for the two-wheel bot): the 0 of the normalized score.
    # Measured once (`bbbench dev random-reference`).
    random_return: float | None = None

    def __post_init__(self) -> None:
        if _TASK_ID.fullmatch(self.id) is None or not self.id.startswith("bbbench/"):
            raise ValueError(f"task IDs look like 'bbbench/Name-vN', got {self.id!r}")
        if not 0.0 <= self.initial_pitch < FALL_TILT:
            raise ValueError(
                f"initial_pitch must be in [0, {FALL_TILT:.3f}) rad (the fall limit), "
                f"got {self.initial_pitch!r}"
            )
        if not self.control_dt > 0 or self.max_episode_steps < 1 or self.physics_substeps < 1:
            raise ValueError(
                f"{self.id}: control_dt > 0, max_episode_steps >= 1 and physics_substeps >= 1 "
                f"are required, got {self.control_dt!r}, {self.max_episode_steps!r}, "
                f"{self.physics_substeps!r}"
            )
        if self.robot not in ROBOTS:
            raise ValueError(
                f"{self.id}: robot must be one of {', '.join(map(repr, ROBOTS))}, "
                f"got {self.robot!r}"
            )
        self._check_team()
        for name in self.robots or (self.robot,):
            top_speed = ROBOTS[name].top_speed
            if not self.command.top_target <= top_speed:
                raise ValueError(
                    f"{self.id}: the command asks for up to {self.command.top_target:g} m/s, "
                    f"beyond the {name} robot's top speed {top_speed:g} m/s"
                )
        if self.scenario is None:
            object.__setattr__(self, "scenario", implied_scenario(self.group))
        if self.scenario not in SCENARIOS:
            raise ValueError(
                f"{self.id}: scenario must be one of {', '.join(map(repr, SCENARIOS))}, "
                f"got {self.scenario!r}"
            )
        refused = SCENARIOS[self.scenario].refusal(self)
        if refused:
            raise ValueError(refused)
        if len(set(self.eval_seeds)) != len(self.eval_seeds):
            raise ValueError(f"{self.id}: eval_seeds must not repeat")
        if any(seed in TRAINING_SEEDS for seed in self.eval_seeds):
            raise ValueError(f"{self.id}: eval_seeds must lie outside the training seeds")
        if len(set(self.validation_seeds)) != len(self.validation_seeds) or any(
            seed in TRAINING_SEEDS or seed in self.eval_seeds for seed in self.validation_seeds
        ):
            raise ValueError(
                f"{self.id}: validation_seeds must not repeat and must lie outside the "
                f"training and evaluation seeds"
            )
        if self.height_scan is not False and self.height_scan is not True:
            raise ValueError(f"height_scan must be True or False, got {self.height_scan!r}")
        if self.height_scan and self.group is not None:
            raise ValueError(f"{self.id}: the height scan is a single-bot option")
        if self.channel is not None and self.group is None:
            raise ValueError(f"{self.id}: a message channel needs several bots (a Group)")

    def _check_team(self) -> None:
        """A mixed team (`robots`): several bots, known robots, `robot` first, two kinds
        at least, and an action mode every one of them takes."""
        if not self.robots:
            return
        names = tuple(self.robots)
        unknown = [name for name in names if name not in ROBOTS]
        if self.group is None or unknown or len(set(names)) < 2 or names[0] != self.robot:
            raise ValueError(
                f"{self.id}: a mixed team's robots are two or more of "
                f"{', '.join(map(repr, ROBOTS))}, the first the task's robot "
                f"({self.robot!r}), on a multi-bot task (a Group); got {self.robots!r}"
            )
        object.__setattr__(self, "robots", names)
        if self.channel is not None:
            raise ValueError(f"{self.id}: a mixed team has no message channel")
        if not self.action_modes:
            raise ValueError(f"{self.id}: the robots {names} share no action mode")

    @property
    def robot_model(self) -> Robot:
        """The robot the task plays (a mixed team's first robot, its leader's): its body,
        action spaces and observation layout."""
        return robot(self.robot)

    @property
    def mixed(self) -> bool:
        """Whether the team mixes robots (`robots`): each keeps its own spaces."""
        return bool(self.robots)

    @property
    def bot_robots(self) -> tuple[Robot, ...]:
        """The robot of each bot, in order: a mixed team's cycle of `robots`, else `robot`
        for every bot."""
        n = self.group.n_bots if self.group is not None else 1
        return tuple(robot(team_robot(self.robots or (self.robot,), i)) for i in range(n))

    @property
    def robot_groups(self) -> dict[str, tuple[int, ...]]:
        """The bots each robot plays, by robot name, in order (one entry but on a mixed
        team): the agent groups a MARL library trains one policy each for."""
        groups: dict[str, list[int]] = {}
        for i, model in enumerate(self.bot_robots):
            groups.setdefault(model.name, []).append(i)
        return {name: tuple(bots) for name, bots in groups.items()}

    @property
    def action_modes(self) -> tuple[str, ...]:
        """The action modes every bot of the task takes, the first robot's order."""
        models = [robot(name) for name in self.robots or (self.robot,)]
        return tuple(m for m in models[0].action_modes if all(m in r.action_modes for r in models))

    @property
    def default_action_mode(self) -> str:
        return self.action_modes[0]

    def check_action_mode(self, action_mode: str) -> None:
        """A clear ValueError for an action mode some bot of the task does not take."""
        if not self.mixed:
            self.robot_model.check_action_mode(action_mode)
        elif action_mode not in self.action_modes:
            raise ValueError(
                f"action_mode must be one of {self.action_modes} for {self.id}'s team of "
                f"{' and '.join(self.robots)} robots, got {action_mode!r}"
            )

    @property
    def scenario_class(self) -> type[Scenario]:
        """The task's rules: `Scene` makes one of these per world."""
        return SCENARIOS[self.scenario]

    def action_space(self, action_mode: str, bot: int = 0) -> spaces.Space:
        """Bot `bot`'s action space: its robot's in `action_mode`, grown by the message
        values where the task has a channel (`bbbench.tasks.channel`)."""
        model = self.bot_robots[bot] if self.mixed else self.robot_model
        space = model.action_space(action_mode)
        return space if self.channel is None else self.channel.action_space(space)

    def action_spaces(self, action_mode: str) -> list[spaces.Space]:
        """Every bot's action space, in order: one object per robot, shared by its bots."""
        own: dict[str, spaces.Space] = {}
        for i, model in enumerate(self.bot_robots):
            if model.name not in own:
                own[model.name] = self.action_space(action_mode, i)
        return [own[model.name] for model in self.bot_robots]

    @property
    def difficulty(self) -> float | None:
        """The terrain's difficulty in [0, 1]; None for flat ground."""
        return getattr(self.terrain, "difficulty", None)

    def with_difficulty(self, difficulty: float) -> TaskSpec:
        """The same task on terrain of another difficulty (a different fingerprint)."""
        if not isinstance(self.terrain, HeightfieldTerrain):
            raise TypeError(f"{self.id} is on flat ground: it takes no difficulty")
        self.terrain.generator.height_bounds(difficulty)  # a clear error for a wrong value
        terrain = dataclasses.replace(self.terrain, difficulty=difficulty)
        return dataclasses.replace(self, terrain=terrain)

    @property
    def multi_agent(self) -> bool:
        """Whether the task is several bots in one world (`bbbench.make_parallel`)."""
        return self.group is not None

    def with_n_bots(self, n_bots: int) -> TaskSpec:
        """The same multi-bot task with another number of bots (a different fingerprint)."""
        if self.group is None:
            raise TypeError(f"{self.id} has one bot: it takes no n_bots")
        most = self.scenario_class.most_bots
        try:
            count = operator.index(n_bots)
        except TypeError:
            count = None
        if most is not None and (count is None or not MIN_BOTS <= count <= most):
            raise ValueError(  # the scenario's range, narrower than any group's
                f"{self.id}: n_bots must be from {MIN_BOTS} to {most} for the "
                f"{self.scenario_class.name!r} scenario, got {n_bots!r}"
            )
        return dataclasses.replace(self, group=dataclasses.replace(self.group, n_bots=n_bots))

    def with_channel(
        self,
        message_width: int | None = None,
        comm_range: float | None = None,
        mute_messages: bool | None = None,
    ) -> TaskSpec:
        """The same task with its channel's width, range or muting changed (a different
        fingerprint); `TypeError` for a task without a channel, `ValueError` (one line) for
        a value out of bounds."""
        if self.channel is None:
            raise TypeError(f"{self.id} has no message channel: it takes no message options")
        changes = {"width": message_width, "range": comm_range, "muted": mute_messages}
        given = {key: value for key, value in changes.items() if value is not None}
        return dataclasses.replace(self, channel=dataclasses.replace(self.channel, **given))

    def with_height_scan(self, height_scan: bool = True) -> TaskSpec:
        """The same task observed with (or without) the ground heights ahead of the bot:
        another observation space, and so a different fingerprint."""
        return dataclasses.replace(self, height_scan=height_scan)

    def with_perturbation(self, component: Any) -> TaskSpec:
        """The same task with `component` in place of the perturbation of its kind; one that
        leaves the task as built (at its default) is dropped: it makes the very same task.
        A task that has one of the kind keeps its other fields (PushRecovery's growth)."""
        if type(component) not in PERTURBATIONS.values():
            raise TypeError(f"{component!r} is not a perturbation ({', '.join(PERTURBATIONS)})")
        kept = [p for p in self.perturbations if type(p) is not type(component)]
        own = [p for p in self.perturbations if type(p) is type(component)]
        if own:  # the task has one (PushRecovery's pushes): the new value, its other fields
            value = dataclasses.fields(component)[0].name
            component = dataclasses.replace(own[0], **{value: getattr(component, value)})
        if not component.leaves_as_built(self):
            kept.append(component)
        return dataclasses.replace(self, perturbations=tuple(sorted(kept, key=lambda p: p.keyword)))

    def with_time_limit(self, max_episode_steps: int) -> TaskSpec:
        """The same task with another time limit (a different fingerprint)."""
        try:
            if isinstance(max_episode_steps, bool | np.bool_):
                raise TypeError
            steps = operator.index(max_episode_steps)  # 10 and np.int64(10), not 2.5 or '10'
        except TypeError:
            steps = 0
        if steps < 1:
            raise ValueError(
                f"max_episode_steps must be a whole number of steps >= 1, got {max_episode_steps!r}"
            )
        return dataclasses.replace(self, max_episode_steps=steps)

    @property
    def max_return(self) -> float:
        """The best possible episode return (per bot): every step upright and on target."""
        return self.reward.max_step * self.max_episode_steps

    def seeds(self, split: str = "evaluation") -> tuple[int, ...]:
        """The task's public seeds of a split: 'evaluation' (what the board scores) or
        'validation' (what choices are made on)."""
        if split not in SEED_SPLITS:
            raise ValueError(
                f"the seeds are {' or '.join(map(repr, SEED_SPLITS))}, got {split!r}: "
                f"choose on 'validation', score on 'evaluation'"
            )
        return self.eval_seeds if split == "evaluation" else self.validation_seeds

    @property
    def spec_hash(self) -> str:
        """A hash of everything that decides the task's behaviour, robot model included."""
        return _spec_hash(self)

    @property
    def name(self) -> str:
        """'Bumps' for 'bbbench/Bumps-v0': the task without namespace or version."""
        return parse_task_id(self.id)[1]

    @property
    def version(self) -> int:
        """0 for 'bbbench/Bumps-v0'."""
        return parse_task_id(self.id)[2]

    @property
    def fingerprint(self) -> str:
        """The spec's hash with the stored golden-rollout hash of its ID (`bbbench dev golden`).

        tests/test_versions.py checks that every registered ID still produces the
        stored rollout, so an ID's fingerprint changes only with a new version.
        """
        rollout = _stored_golden().get(self.id, {}).get("rollout", "not pinned")
        return hashlib.sha256(f"{self.spec_hash}:{rollout}".encode()).hexdigest()[:16]


def _behaviour_hash(task: TaskSpec) -> str:
    """`TaskSpec.spec_hash`, computed: everything that decides the task's behaviour."""
    behaviour = {
        key: value
        for key, value in _published_options(dataclasses.asdict(task)).items()
        if key not in _NOT_BEHAVIOUR_FIELDS
    }
    if task.scenario == implied_scenario(task.group):  # as published: not hashed
        del behaviour["scenario"]
    # Class names tell apart components whose fields happen to match: those of the
    # first published specs, in their order, then every other component found.
    published = [
        task.terrain,
        getattr(task.terrain, "generator", None),
        task.command,
        task.sensors,
        task.reward,
        task.group,
    ]
    behaviour["components"] = [type(component).__name__ for component in published] + [
        type(component).__name__
        for component in _components(task)[1:]  # [0] is the spec itself
        if not any(component is known for known in published)
    ]
    digest = hashlib.sha256(json.dumps(behaviour, sort_keys=True).encode())
    digest.update(task.robot_model.urdf_path.read_bytes())
    for name in task.robots[1:]:  # a mixed team's other robots
        digest.update(robot(name).urdf_path.read_bytes())
    return digest.hexdigest()[:16]


_SPEC_HASHES: dict[str, str] = {}  # repr(spec): its hash


def _spec_hash(task: TaskSpec) -> str:
    """`TaskSpec.spec_hash`, once per spec: a board asks for the fingerprints of the same
    few specs thousands of times. Keyed by the spec's repr, which tells 1 from 1.0 as the
    hash does (equal specs may not)."""
    key = repr(task)
    if key not in _SPEC_HASHES:
        if len(_SPEC_HASHES) >= 4096:  # a long sweep's variants: keep memory bounded
            _SPEC_HASHES.clear()
        _SPEC_HASHES[key] = _behaviour_hash(task)
    return _SPEC_HASHES[key]


# The golden-rollout hashes stored for each task ID: data that `bbbench.dev.golden`
# (the tool above the envs that computes them) writes, and the fingerprint reads.
GOLDEN_FILE = Path(__file__).with_name("golden.json")


@functools.cache
def _stored_golden() -> dict[str, dict[str, str]]:
    return json.loads(GOLDEN_FILE.read_text()) if GOLDEN_FILE.exists() else {}
