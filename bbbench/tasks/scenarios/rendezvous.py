"""`Rendezvous`: steering bots that must gather at the one of four landmarks only one of
them is told, and can say so over a message channel (`bbbench.tasks.channel`); and
the task it plays (`TASKS`).

MPE's speaker-listener, on balancing robots and for a team. Each episode draws four
landmarks on a circle of `LANDMARK_RADIUS` m (turned at random: the same four places
for every bot, in the same order), the *scout*, one bot of the group, and the goals: a
landmark held `HOLD` s, then another (`goal_schedule`). Only the scout observes which
landmark is the goal now (`goal_is_landmark{k}`, a one-hot; zeros for every other
bot). Every bot observes every landmark's distance and bearing, its nearest neighbours
within `SENSED_RANGE` m (too short to watch the scout from afar) and, through the
channel, the messages of the nearest bots within the channel's range, beside where they
are. Nothing but a message tells a bot which landmark it is, or which bot is the scout.

Each bot tracks a velocity towards the goal that stops as it gathers,

    target = min(speed, ARRIVAL_RATE x max(distance to the goal - GATHERED, 0))

and its share is the shared reward (`StayUpReward`, 0 to 0.1 a step) on
|velocity . unit(goal - axle) - target|. The team earns together: every live bot's
reward is the mean of the group's shares, a fallen bot's share 0 from its fall on (so a
bot that tells the others the goal earns by their driving, and a fall costs the team).
A bot that falls ends its own episode and leaves the world, as on Swap.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bbbench.portable import total
from bbbench.robots.layout import ObservationField
from bbbench.tasks.channel import Channel
from bbbench.tasks.commands import SPEED_TARGETS
from bbbench.tasks.group import Group, nearest_others, spawn_poses
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
from bbbench.tasks.spec import TaskSpec

LANDMARKS = 4
LANDMARK_RADIUS = 2.0  # m: the landmarks' circle about the origin
GATHERED = 1.0  # m: within this of the goal a bot's target is to stand
ARRIVAL_RATE = 1.0  # 1/s: the target speed near the goal, per m beyond GATHERED
SEEN_DISTANCE = 10.0  # m: landmark distances are observed up to this
SENSED_RANGE = 1.0  # m: the neighbour block's range (the channel's reaches farther)
HOLD = (3.0, 6.0)  # s: how long each goal holds before the goal moves to another landmark
MOST_BOTS = 8
_GOAL_COLOUR, _OTHER_COLOUR = (0.9, 0.2, 0.2, 1.0), (0.6, 0.6, 0.6, 1.0)


def _landmark_fields() -> tuple[ObservationField, ...]:
    fields = []
    for k in range(LANDMARKS):
        fields += [
            ObservationField(f"landmark{k}_distance", "m", 0.0, SEEN_DISTANCE,
                             f"distance to landmark {k}"),
            ObservationField(f"landmark{k}_cos", "", -1.0, 1.0,
                             "cosine of its bearing (1: dead ahead)"),
            ObservationField(f"landmark{k}_sin", "", -1.0, 1.0,
                             "sine of its bearing (+: to the left)"),
        ]  # fmt: skip
    fields += [
        ObservationField(f"goal_is_landmark{k}", "", 0.0, 1.0,
                         f"1 if landmark {k} is the goal and this bot the scout, else 0")
        for k in range(LANDMARKS)
    ]  # fmt: skip
    return tuple(fields)


_OWN_FIELDS = _landmark_fields()


def goal_schedule(rng: np.random.Generator, steps: int, control_dt: float) -> list[tuple[int, int]]:
    """The episode's goals: (first step, landmark) pairs from step 0 past `steps`, each
    goal held `HOLD` s (uniform) and the next drawn among the other landmarks."""
    low, high = (round(seconds / control_dt) for seconds in HOLD)
    schedule = [(0, int(rng.integers(LANDMARKS)))]
    while schedule[-1][0] <= steps:
        start, goal = schedule[-1]
        other = (goal + 1 + int(rng.integers(LANDMARKS - 1))) % LANDMARKS
        schedule.append((start + int(rng.integers(low, high + 1)), other))
    return schedule


@register_scenario
class Rendezvous(Scenario):
    """The group's steering bots around a circle (`spawn_poses`), four landmarks within
    it, one the goal that only the scout knows (the module's docstring). Each observes
    its robot's layout, the landmarks, the goal if it is the scout, its neighbours
    within `SENSED_RANGE` m, then the channel's message block; the team earns the mean
    of its bots' shares, and a bot that falls ends its own episode and leaves."""

    name = "rendezvous"
    summary = "steering bots gathering at the landmark only one of them is told, over a channel"
    multi_agent = True
    robots = ("two-wheel-steer",)
    metrics = ("velocity_error", "goal_distance")
    most_bots = MOST_BOTS
    controller = "rendezvous"  # bbbench.policies.controllers.rendezvous
    reward_type = StayUpReward

    def __init__(self, task) -> None:
        super().__init__(task)
        self.group, self.channel = task.group, task.channel
        robot = self.robot.layout()
        neighbours = neighbour_layout(task.group)
        self._own = len(robot) + len(_OWN_FIELDS) + len(neighbours)
        self.layout = (*robot, *_OWN_FIELDS, *neighbours, *task.channel.layout())
        self._size = len(self.layout)
        self._heard = max(task.group.neighbours, task.channel.slots)  # others to sort
        self.landmarks: list[tuple[float, float]] = []
        self.goal = 0  # the goal's landmark now
        self.schedule: list[tuple[int, int]] = [(0, 0)]  # (first step, landmark) of each goal
        self._next = 1
        self.scout = 0  # the bot told the goal
        self._shares: list[float] = []  # each bot's last share; 0 once it has left
        self._seen: tuple[list, list, list] = ([], [], [])
        self._live: list[int] = []  # the live bots' indices at the last observation

    @classmethod
    def refusal(cls, task) -> str | None:
        refused = super().refusal(task)
        if refused:
            return refused
        if task.channel is None:
            return f"{task.id}: the {cls.name!r} scenario needs a message channel (Channel)"
        return None

    def build(self, client: Any, bots: tuple[Any, ...]) -> None:
        self._client = client
        self._markers: list[int] = []  # what `draw` shows of the landmarks

    def draw(self, scene: Any) -> None:
        """The landmarks as discs on the ground, the goal red: bodies without mass or
        collision shape, made at the first frame."""
        client = self._client
        if not self._markers:
            self._markers = discs(client, LANDMARKS, 0.2, _OTHER_COLOUR)
        for k, (body, (x, y)) in enumerate(zip(self._markers, self.landmarks, strict=True)):
            place_disc(client, body, x, y, colour=_GOAL_COLOUR if k == self.goal else _OTHER_COLOUR)

    def starts(self, rng: np.random.Generator) -> tuple[list[Pose], list[float]]:
        """The bots as on Swap, then the landmarks' turn, the scout and the goals."""
        n, pitch = self.group.n_bots, self.task.initial_pitch
        poses = spawn_poses(rng, self.group)
        pitches = list(rng.uniform(-pitch, pitch, size=n))
        turn = float(rng.uniform(0.0, 2.0 * math.pi / LANDMARKS))
        self.landmarks = [
            (
                LANDMARK_RADIUS * math.cos(turn + k * 2.0 * math.pi / LANDMARKS),
                LANDMARK_RADIUS * math.sin(turn + k * 2.0 * math.pi / LANDMARKS),
            )
            for k in range(LANDMARKS)
        ]
        self.scout = int(rng.integers(n))
        self.schedule = goal_schedule(rng, self.task.max_episode_steps, self.task.control_dt)
        self.goal = self.schedule[0][1]
        self._next = 1  # the schedule's next change
        self._shares = [0.0] * n
        return poses, pitches

    def slots(self) -> Slots:
        """The own values (robot, landmarks, goal, neighbour block), then the channel's
        senders: where each is and what it said, its presence bit last."""
        width = self.channel.width + 3
        return Slots(self._own, self.channel.slots, width, width - 1)

    def observe(
        self, scene: Any, states: list[Any], commands: list[float], targets: list[float], step: int
    ) -> np.ndarray:
        """The live bots' observations, one row each: the robot's layout, the landmarks'
        distance and bearing, the goal's one-hot (the scout's alone), the neighbours
        within `SENSED_RANGE` m, the message block (`Channel.blocks`, from what each live
        bot sent with its last action). What `outcome` needs is kept."""
        self._live = live = list(scene.live)
        schedule = self.schedule
        if self._next < len(schedule) and step >= schedule[self._next][0]:
            self.goal = schedule[self._next][1]  # the goal moves on
            self._next += 1
        goal, scout, seen, sqrt = self.goal, self.scout, SEEN_DISTANCE, math.sqrt
        told = tuple(1.0 if k == goal else 0.0 for k in range(LANDMARKS))
        untold = (0.0,) * LANDMARKS
        landmarks = self.landmarks
        goal_x, goal_y = landmarks[goal]
        extras, limited, distances, towards = [], [], [], []
        for i, state, speed in zip(live, states, targets, strict=True):
            x, y, _ = state.axle
            hx, hy = state.heading
            row: list[float] = []
            for lx, ly in landmarks:
                dx, dy = lx - x, ly - y
                distance = sqrt(dx * dx + dy * dy)  # correctly rounded: any CPU
                if distance > 0.0:
                    cos, sin = (hx * dx + hy * dy) / distance, (hx * dy - hy * dx) / distance
                    cos = 1.0 if cos > 1.0 else -1.0 if cos < -1.0 else cos  # rounding aside
                    sin = 1.0 if sin > 1.0 else -1.0 if sin < -1.0 else sin
                else:
                    cos, sin = 1.0, 0.0
                row += (distance if distance < seen else seen, cos, sin)
            row += told if i == scout else untold
            extras.append(row)
            # The goal's landmark again, outside the loop (the same arithmetic, the same bits).
            dx, dy = goal_x - x, goal_y - y
            distance = sqrt(dx * dx + dy * dy)
            vx, vy = state.velocity
            distances.append(distance)
            towards.append((vx * dx + vy * dy) / distance if distance > 0.0 else 0.0)
            near = ARRIVAL_RATE * max(distance - GATHERED, 0.0)
            limited.append(near if near < speed else speed)
        self._seen = distances, limited, towards
        # Each bot's others, nearest first, once for both blocks; their positions once.
        positions = [complex(state.position[0], state.position[1]) for state in states]
        nearest = nearest_others(positions, self._heard)
        sent = scene.sent
        blocks = self.channel.blocks(states, [sent[i] for i in live], nearest, positions)
        return group_observations(
            self.robot, states, commands, targets, self.group, self._size, extras, blocks,
            nearest, positions=positions,
        )  # fmt: skip

    def outcome(
        self, agents: list[str], states: list[Any], targets: list[float], seed: int
    ) -> Outcome:
        """The team's reward for every live bot: the mean over the group of each bot's
        share (its shared reward for its velocity towards the goal; 0 for a bot that has
        left); whether each fell (which ends that bot's episode), and its info: its
        share's two terms, `velocity_error` (m/s), `goal_distance` (m), `episode_seed`."""
        live = self._live  # as `observe` saw them: it runs first, on the same states
        shares, fell, infos = self._shares, [], []
        terms = self.reward.terms
        for i, state, distance, target, toward in zip(live, states, *self._seen, strict=True):
            velocity_error = abs(toward - target)
            upright, tracking = terms(state.pitch, velocity_error)
            down = has_fallen(state)
            shares[i] = 0.0 if down else upright + tracking
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
        team = total(shares) / len(shares)
        return Outcome([team] * len(live), fell, False, fell_cause(agents, fell), infos)

    def leave(self, scene: Any, indices: list[int]) -> None:
        """Out of the world: set aside, far away, colliding with nothing; its share 0."""
        for i in indices:
            self._shares[i] = 0.0
        scene.take_out(indices)


TASKS = (
    TaskSpec(
        id="bbbench/Rendezvous-v0",
        summary="4 steering bots (2-8) gather at the landmark only one is told, over a channel",
        description=f"""\
Several steering bots (4 by default, `n_bots` 2-{MOST_BOTS}) start spread around a circle of
4 m radius facing its centre, on flat ground. Four landmarks lie on a circle of
{LANDMARK_RADIUS:g} m, turned at random; one is the goal, and one bot drawn each episode,
the scout, is told which (a one-hot only it observes). Every {HOLD[0]:g}-{HOLD[1]:g} s the goal
moves to another landmark, and the scout is told. The team must gather at the goal: each
bot's target speed towards it, drawn from [1, 2] m/s and held 2-5 s, stops within
{GATHERED:g} m of it ({ARRIVAL_RATE:g}/s x the distance beyond). Every bot observes the steering
robot's eight values, each landmark's distance and bearing, its 3 nearest neighbours
within {SENSED_RANGE:g} m, and a message channel: 2 message values per bot in its action,
heard by the 3 nearest bots within 6 m beside where the sender is, one step later
(`bbbench.tasks.channel`; `message_width`, `comm_range` and `mute_messages` change it).
Only a message can tell a bot the goal, or which bot is the scout. The reward is the
team's: every bot earns the mean over the group of each bot's shared reward
(`StayUpReward`) on its velocity towards the goal, a fallen bot's 0. A bot that falls
ends its own episode and leaves the world.""",
        robot="two-wheel-steer",
        scenario="rendezvous",
        command=SPEED_TARGETS,
        reward=StayUpReward(),
        group=Group(spawn_radius=4.0, heading_jitter=0.3, neighbour_range=SENSED_RANGE),
        channel=Channel(width=2, range=6.0, slots=3),
        random_return=0.6546242936604287,
    ),
)
