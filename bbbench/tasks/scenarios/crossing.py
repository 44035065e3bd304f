"""`Crossing`: several bots in one world whose paths cross, each on its own target; and
the tasks it plays, a row each (`TASKS`): MultiBalance, MultiBumps and MultiNoisySensors."""

from __future__ import annotations

from typing import Any

import numpy as np

from bbbench.tasks.commands import FORWARD_TARGETS
from bbbench.tasks.group import Group, spawn_poses
from bbbench.tasks.observation import group_observations, neighbour_layout
from bbbench.tasks.reward import StayUpReward, stay_up_history, step_outcome
from bbbench.tasks.scenario import Outcome, Pose, Scenario, Slots, fell_cause, register_scenario
from bbbench.tasks.sensors import NoisySensors
from bbbench.tasks.spec import TaskSpec
from bbbench.terrain import Bumps, HeightfieldTerrain


@register_scenario
class Crossing(Scenario):
    """The group's bots start around a circle heading for its centre (`spawn_poses`), each
    leaning U(-initial_pitch, initial_pitch). Each observes its robot's layout, then its
    nearest neighbours (`group_observations`), and earns the shared reward for its own
    target; a bot that falls ends its own episode alone and leaves the world (it is no
    obstacle, and no neighbour, to the others)."""

    name = "crossing"
    summary = "bots whose paths cross, each on its own target; a fallen bot leaves the world"
    multi_agent = True
    senses = True

    def __init__(self, task) -> None:
        super().__init__(task)
        self.group = task.group
        self.layout = self.robot.layout() + neighbour_layout(task.group)
        self._size = len(self.layout)

    def starts(self, rng: np.random.Generator) -> tuple[list[Pose], list[float]]:
        pitch = self.task.initial_pitch
        poses = spawn_poses(rng, self.group)
        return poses, list(rng.uniform(-pitch, pitch, size=self.group.n_bots))

    def slots(self) -> Slots:
        """The robot's own values, then the K nearest neighbours' 4 values each."""
        own = self.robot.observation_space().shape[0]
        return Slots(own, self.group.neighbours, (self._size - own) // self.group.neighbours, None)

    def observe(
        self, scene: Any, states: list[Any], commands: list[float], targets: list[float], step: int
    ) -> np.ndarray:
        """The live bots' observations, one row each (`group_observations`), each bot's
        robot values through its own sensors (`Scene.live_readings`)."""
        readings = scene.live_readings(states, step)
        return group_observations(
            self.robot, states, commands, targets, self.group, self._size, readings=readings
        )

    def outcome(
        self, agents: list[str], states: list[Any], targets: list[float], seed: int
    ) -> Outcome:
        """Each live bot's reward and whether it fell (a fall ends that bot's episode
        alone), and its info: the reward's two terms, `velocity_error` and
        `episode_seed` (the same keys at reset and at every step)."""
        rewards, fell, infos = [], [], []
        reward = self.reward
        for state, target in zip(states, targets, strict=True):
            earned, down, info = step_outcome(state, target, reward)
            info["episode_seed"] = seed
            rewards.append(earned)
            fell.append(down)
            infos.append(info)
        return Outcome(rewards, fell, False, fell_cause(agents, fell), infos)

    def leave(self, scene: Any, indices: list[int]) -> None:
        """Out of the world: set aside, far away, colliding with nothing."""
        scene.take_out(indices)


# The tasks: each row states all it sets (`TaskSpec`'s defaults for the rest); the
# constants are what a task's versions share.
_MULTI_BALANCE_SUMMARY = "4 bots (2-16) whose paths cross on flat ground, each at 0.2-0.8 m/s"
_MULTI_BALANCE_DESCRIPTION = (
    "Several bots (4 by default, `n_bots` 2-16) start on a circle facing its centre, "
    "so their paths cross, on flat ground; each follows its own forward target at "
    "0.2-0.8 m/s and leaves the episode when it falls. `bbbench.envs.multi."
    "MultiBalanceEnv` documents the PettingZoo API they share."
)
_MULTI_BUMPS_SUMMARY = "4 bots (2-16) whose paths cross on smooth random hills"
_MULTI_BUMPS_DESCRIPTION = (
    "MultiBalance's bots and targets on a 12 x 12 m square of -v0's smooth random "
    "hills (0.3 default difficulty) around the spawn circle, level along it."
)
_MULTI_BUMPS_TERRAIN = HeightfieldTerrain(
    generator=Bumps(),
    difficulty=0.3,
    # A square around the spawn circle, level along it.
    size=(12.0, 12.0),
    start_margin=6.0,
    start_ring=Group().spawn_radius,
)

TASKS = (
    TaskSpec(
        id="bbbench/MultiBalance-v0",
        summary=_MULTI_BALANCE_SUMMARY,
        description=_MULTI_BALANCE_DESCRIPTION,
        random_return=1.5245667657055884,
        command=FORWARD_TARGETS,
        group=Group(),
    ),
    TaskSpec(
        id="bbbench/MultiBalance-v1",
        summary=_MULTI_BALANCE_SUMMARY,
        description=_MULTI_BALANCE_DESCRIPTION,
        random_return=1.72400817656264,
        command=FORWARD_TARGETS,
        group=Group(),
        reward=StayUpReward(),
        version_history=stay_up_history(("v0: initial release.",), 1),
    ),
    TaskSpec(
        id="bbbench/MultiBumps-v0",
        summary=_MULTI_BUMPS_SUMMARY,
        description=_MULTI_BUMPS_DESCRIPTION,
        random_return=1.5233704486135895,
        terrain=_MULTI_BUMPS_TERRAIN,
        command=FORWARD_TARGETS,
        group=Group(),
    ),
    TaskSpec(
        id="bbbench/MultiBumps-v1",
        summary=_MULTI_BUMPS_SUMMARY,
        description=_MULTI_BUMPS_DESCRIPTION,
        random_return=1.7237354574632304,
        terrain=_MULTI_BUMPS_TERRAIN,
        command=FORWARD_TARGETS,
        group=Group(),
        reward=StayUpReward(),
        version_history=stay_up_history(("v0: initial release.",), 1),
    ),
    TaskSpec(
        id="bbbench/MultiNoisySensors-v0",
        summary="MultiBalance's crossing bots, each through its own biased, noisy sensors",
        description=(
            "MultiBalance-v1's bots, ground, targets and reward, each bot observing its own "
            "state through a biased, noisy IMU and noisy encoders of its own: "
            "NoisySensors-v1's model (the tutorial's noisy variant; a pitch bias of N(0, "
            "0.1) rad for the episode, per-step noise of 0.05 rad, 0.01 rad/s and 0.05 rad/s "
            "on pitch, pitch rate and wheel speed), drawn for each bot in turn from the "
            "episode's sensor stream. What the bots see of each other (the neighbour slots) "
            "is exact. A bot's bias is constant over its episode: a policy that remembers "
            "(a recurrent one) can estimate it, one that does not cannot."
        ),
        random_return=1.72400817656264,
        command=FORWARD_TARGETS,
        group=Group(),
        sensors=NoisySensors(),
        reward=StayUpReward(),
    ),
)
