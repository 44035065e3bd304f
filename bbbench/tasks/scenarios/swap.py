"""`Swap`: steering bots on a circle, each driving to the point opposite its start,
through the others (VMAS' navigation and give_way); and the task it plays (`TASKS`).

The bots start spread around a circle facing its centre (`spawn_poses`), so that every
straight path crosses every other at the middle. A bot's goal is its start mirrored
through the centre. It tracks a velocity towards its goal that slows as it arrives,

    target = min(speed, ARRIVAL_RATE x distance to the goal)

so that a bot that has arrived earns its tracking credit by standing on its goal, and
is an obstacle the others must pass. The reward is the shared form (`StayUpReward`,
0 to 0.1 a step) on |velocity . unit(goal - axle) - target|; a bot that falls ends its
own episode and leaves the world, as on the crossings.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bbbench.robots.layout import ObservationField
from bbbench.tasks.commands import SPEED_TARGETS
from bbbench.tasks.group import NEIGHBOUR_FIELDS, Group, spawn_poses
from bbbench.tasks.observation import group_observations, neighbour_layout
from bbbench.tasks.reward import StayUpReward, has_fallen
from bbbench.tasks.scenario import (
    Outcome,
    Pose,
    Scenario,
    Slots,
    discs,
    fell_cause,
    place_disc,
    register_scenario,
)
from bbbench.tasks.scenarios.waypoints import SEEN_DISTANCE
from bbbench.tasks.spec import TaskSpec

ARRIVAL_RATE = 1.0  # 1/s: the target speed near the goal, per m from it
MOST_BOTS = 8

_GOAL_FIELDS = (
    ObservationField("goal_distance", "m", 0.0, SEEN_DISTANCE, "distance to the goal"),
    ObservationField("goal_cos", "", -1.0, 1.0, "cosine of the goal's bearing (1: dead ahead)"),
    ObservationField("goal_sin", "", -1.0, 1.0, "sine of the goal's bearing (+: to the left)"),
)


@register_scenario
class Swap(Scenario):
    """The group's steering bots on a circle (`spawn_poses`), each to the point opposite
    (the module's docstring). Each observes its robot's layout (its target velocity the
    arrival-limited one), its goal's distance and bearing, then its nearest neighbours
    as on the crossings (`group_observations`); it earns the shared reward for its
    velocity towards its goal, and a bot that falls ends its own episode and leaves."""

    name = "swap"
    summary = "steering bots on a circle, each to the point opposite, through the others"
    multi_agent = True
    robots = ("two-wheel-steer",)
    metrics = ("velocity_error", "goal_distance")
    most_bots = MOST_BOTS
    heads_for = "the goal"
    reward_type = StayUpReward
    # steer-avoid (bbbench.policies.controllers.steer.Avoiding): steer, past the others
    controller = "steer-avoid"

    def __init__(self, task) -> None:
        super().__init__(task)
        self.group = task.group
        self._own = len(self.robot.layout()) + len(_GOAL_FIELDS)
        self.layout = (*self.robot.layout(), *_GOAL_FIELDS, *neighbour_layout(task.group))
        self._size = len(self.layout)
        self.goals: list[tuple[float, float]] = []
        self._live: list[int] = []  # the live bots' indices at the last observation
        # Their goals' distances, their targets and their velocities towards their goals.
        self._seen: tuple[list, list, list] = ([], [], [])

    def build(self, client: Any, bots: tuple[Any, ...]) -> None:
        self._client = client
        self._markers: list[int] = []  # what `draw` shows of the goals

    @property
    def markers(self) -> tuple[int, ...]:
        """The bodies `draw` shows of the goals (none before the first frame drawn)."""
        return tuple(self._markers)

    def draw(self, scene: Any) -> None:
        """Each bot's goal as a grey disc on the ground: bodies without mass or collision
        shape, made at the first frame."""
        client = self._client
        if not self._markers:
            self._markers = discs(client, len(self.goals), 0.2, (0.6, 0.6, 0.6, 1.0))
        for body, (x, y) in zip(self._markers, self.goals, strict=True):
            place_disc(client, body, x, y)

    def starts(self, rng: np.random.Generator) -> tuple[list[Pose], list[float]]:
        pitch = self.task.initial_pitch
        poses = spawn_poses(rng, self.group)
        self.goals = [(-x, -y) for (x, y), _ in poses]
        return poses, list(rng.uniform(-pitch, pitch, size=self.group.n_bots))

    def slots(self) -> Slots:
        """The robot's own values and the goal, then the K nearest neighbours' 4 values."""
        k = self.group.neighbours
        return Slots(self._own, k, len(NEIGHBOUR_FIELDS), None)

    def observe(
        self, scene: Any, states: list[Any], commands: list[float], targets: list[float], step: int
    ) -> np.ndarray:
        """The live bots' observations, one row each: the robot's layout (the target the
        arrival-limited one), the goal's distance and bearing (`bearing`'s arithmetic,
        written out: this runs every step), the neighbours (`group_observations`). What
        `outcome` needs of the goals is kept: it runs next, on the same states."""
        self._live = live = list(scene.live)
        goals, rate, seen = self.goals, ARRIVAL_RATE, SEEN_DISTANCE
        extras, limited, distances, towards = [], [], [], []
        for i, state, speed in zip(live, states, targets, strict=True):
            x, y, _ = state.axle
            gx, gy = goals[i]
            dx, dy = gx - x, gy - y
            distance = math.sqrt(dx * dx + dy * dy)
            if distance > 0.0:
                hx, hy = state.heading
                cos, sin = (hx * dx + hy * dy) / distance, (hx * dy - hy * dx) / distance
                cos = 1.0 if cos > 1.0 else -1.0 if cos < -1.0 else cos  # rounding aside
                sin = 1.0 if sin > 1.0 else -1.0 if sin < -1.0 else sin
                vx, vy = state.velocity
                towards.append((vx * dx + vy * dy) / distance)
            else:
                cos, sin = 1.0, 0.0
                towards.append(0.0)
            near = rate * distance
            limited.append(near if near < speed else speed)
            distances.append(distance)
            extras.append((distance if distance < seen else seen, cos, sin))
        self._seen = distances, limited, towards
        return group_observations(
            self.robot, states, commands, limited, self.group, self._size, extras
        )

    def outcome(
        self, agents: list[str], states: list[Any], targets: list[float], seed: int
    ) -> Outcome:
        """Each live bot's reward for its velocity towards its goal, whether it fell (a
        fall ends that bot's episode alone), and its info: the reward's two terms,
        `velocity_error` (m/s), `goal_distance` (m) and `episode_seed`. The goals as
        `observe` saw them: it runs first, on the same states."""
        rewards, fell, infos = [], [], []
        terms = self.reward.terms
        for state, distance, target, toward in zip(states, *self._seen, strict=True):
            velocity_error = abs(toward - target)
            upright, tracking = terms(state.pitch, velocity_error)
            down = has_fallen(state)
            rewards.append(upright + tracking)
            fell.append(down)
            infos.append(
                {
                    "reward_upright": upright,
                    "reward_velocity": tracking,
                    "velocity_error": velocity_error,
                    "goal_distance": distance,
                    "episode_seed": seed,
                }
            )
        return Outcome(rewards, fell, False, fell_cause(agents, fell), infos)

    def leave(self, scene: Any, indices: list[int]) -> None:
        """Out of the world: set aside, far away, colliding with nothing."""
        scene.take_out(indices)


TASKS = (
    TaskSpec(
        id="bbbench/Swap-v0",
        summary="4 steering bots (2-8) on a circle, each to the point opposite, through the others",
        description=f"""\
Several steering bots (4 by default, `n_bots` 2-{MOST_BOTS}) start spread around a circle of
3 m radius facing its centre, on flat ground; each must drive to the point opposite its
start, so every straight path crosses every other at the middle (VMAS' navigation and
give_way). Each bot's target speed is drawn from [1, 2] m/s and held 2-5 s, and
limited near its goal to {ARRIVAL_RATE:g}/s x its distance, so that a bot that has arrived
stands on its goal. It observes the steering robot's eight values, its goal's distance
and bearing (cosine and sine, + to the left), then its 3 nearest neighbours within 5 m
as on MultiBalance. The reward is the shared one (`StayUpReward`) on the velocity
towards the goal: |velocity . unit(goal - axle) - target|. A bot that falls ends its own
episode and leaves the world. `bbbench.envs.multi.MultiBalanceEnv` documents the
PettingZoo API.""",
        robot="two-wheel-steer",
        scenario="swap",
        command=SPEED_TARGETS,
        reward=StayUpReward(),
        group=Group(spawn_radius=3.0, heading_jitter=0.0),
        random_return=0.6887960389410176,
    ),
)
