"""`Waypoints`: one steering bot driving through a seeded course of waypoints, on flat
ground or over hills; and the tasks it plays (`TASKS`).

The course is `COURSE_POINTS` points drawn uniformly in a disc of `COURSE_RADIUS` m around
the start, each at least `MIN_LEG` m from the one before (the first from the start), from
the episode's start stream: its legs turn any way, up to turning back. The bot's goal is
the first point it has not reached; it reaches it within `REACH` m of its axle, and the
goal moves to the next. The course is longer than an episode can drive.

The reward is the shared form (`StayUpReward`, 0 to 0.1 a step) with the velocity it
tracks made two-dimensional: the axle's horizontal velocity along the direction to the
goal, against the task's target speed,

    velocity_error = |velocity . (goal - axle) / |goal - axle| - target speed|

so a bot earns its tracking credit driving straight at its goal at the target speed, and
less for every degree it is off (at 90 degrees it is as far from target as standing).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bbbench.robots.layout import ObservationField, observation_with
from bbbench.robots.steering import SteerState, own_values
from bbbench.tasks.commands import PiecewiseConstantVelocity
from bbbench.tasks.reward import StayUpReward, has_fallen
from bbbench.tasks.scenario import Outcome, discs, place_disc, register_scenario
from bbbench.tasks.scenarios.solo import Solo
from bbbench.tasks.spec import TaskSpec
from bbbench.terrain import Bumps, HeightfieldTerrain

COURSE_RADIUS = 5.0  # m: every waypoint lies within this of the start
MIN_LEG = 2.0  # m: the least distance from a waypoint to the one before
COURSE_POINTS = 24  # more than an episode reaches: 15 s at 1.5 m/s is 11 legs of 2 m
REACH = 0.3  # m: a waypoint is reached within this of the axle
SEEN_DISTANCE = 2 * COURSE_RADIUS  # m: the farthest a goal can be (observed up to this)
SHOWN = 4  # waypoints a frame shows: the goal and the ones after it
_GOAL_COLOUR, _LATER_COLOUR = (0.9, 0.2, 0.2, 1.0), (0.6, 0.6, 0.6, 1.0)

_GOAL_FIELDS = (
    ObservationField("goal_distance", "m", 0.0, SEEN_DISTANCE, "distance to the goal"),
    ObservationField("goal_cos", "", -1.0, 1.0, "cosine of the goal's bearing (1: dead ahead)"),
    ObservationField("goal_sin", "", -1.0, 1.0, "sine of the goal's bearing (+: to the left)"),
    ObservationField("next_distance", "m", 0.0, SEEN_DISTANCE, "distance to the goal after it"),
    ObservationField("next_cos", "", -1.0, 1.0, "cosine of that goal's bearing"),
    ObservationField("next_sin", "", -1.0, 1.0, "sine of that goal's bearing (+: to the left)"),
)


def draw_course(rng: np.random.Generator) -> list[tuple[float, float]]:
    """A course: `COURSE_POINTS` points uniform in the disc of `COURSE_RADIUS` m around the
    origin, each at least `MIN_LEG` m from the one before. Rejection sampling from the
    square: no trigonometry, so the same bits on every CPU."""
    course: list[tuple[float, float]] = []
    last = (0.0, 0.0)
    radius2, leg2 = COURSE_RADIUS * COURSE_RADIUS, MIN_LEG * MIN_LEG
    while len(course) < COURSE_POINTS:
        x, y = (float(value) for value in rng.uniform(-COURSE_RADIUS, COURSE_RADIUS, 2))
        if x * x + y * y <= radius2 and (x - last[0]) ** 2 + (y - last[1]) ** 2 >= leg2:
            course.append((x, y))
            last = (x, y)
    return course


def bearing(state: Any, point: tuple[float, float]) -> tuple[float, float, float]:
    """(distance, cos, sin) of `point` from the bot's axle: its distance (m) and the cosine
    and sine of its bearing from the bot's heading (+ sine: to the left)."""
    x, y, _ = state.axle
    hx, hy = state.heading
    dx, dy = point[0] - x, point[1] - y
    distance = math.sqrt(dx * dx + dy * dy)  # correctly rounded: the same on any CPU
    if distance == 0.0:
        return 0.0, 1.0, 0.0
    cos, sin = (hx * dx + hy * dy) / distance, (hx * dy - hy * dx) / distance
    return distance, min(max(cos, -1.0), 1.0), min(max(sin, -1.0), 1.0)  # rounding aside


# The rows published while `BalanceEnv` scored a step before it observed it: their
# `outcome` reads the goal as it stood before this step's `observe` moved it on, and the
# reach the step before counted (the reward at a reached point and `waypoints_per_minute`
# one step late). They keep those episodes, bit for bit; a new version scores the step's
# own goal (issue 66: one step protocol, `Scenario.observe_and_score`).
SCORED_AS_PUBLISHED = frozenset({"bbbench/Waypoints-v0", "bbbench/WaypointsBumps-v0"})


@register_scenario
class Waypoints(Solo):
    """One steering bot, started as `Solo`'s (at the origin heading along +y), driving
    through a course of waypoints drawn at each reset (the module's docstring). It
    observes its robot's layout (its target velocity the task's target speed), then the
    distance and bearing of its goal and of the goal after it; it earns the shared reward
    for its velocity towards the goal, and a fall ends it."""

    name = "waypoints"
    summary = "one steering bot driving through a seeded course of waypoints"
    robots = ("two-wheel-steer",)
    metrics = ("velocity_error", "waypoints_per_minute")
    scans_ground = False
    heads_for = "the goal"
    reward_type = StayUpReward

    def __init__(self, task) -> None:
        super().__init__(task)
        self.layout = (*self.robot.layout(), *_GOAL_FIELDS)
        self.course: list[tuple[float, float]] = []
        self.goal = 0  # the index of the first point not reached
        self._reached = False  # whether the last observed step reached a point
        self._per_minute = 60.0 / task.control_dt  # steps in a minute
        # The goal and the reach `outcome` scores: this step's, or on the rows published
        # before the step protocol (`SCORED_AS_PUBLISHED`), those before it.
        self._late = task.id in SCORED_AS_PUBLISHED
        self._scored = (0, False)

    def build(self, client: Any, bots: tuple[Any, ...]) -> None:
        self._client = client
        self._markers: list[int] = []  # what `draw` shows of the course

    @property
    def markers(self) -> tuple[int, ...]:
        """The bodies `draw` shows of the course (none before the first frame drawn)."""
        return tuple(self._markers)

    def draw(self, scene: Any) -> None:
        """The goal (red) and the next waypoints (grey) as discs on the ground: bodies
        without mass or collision shape, made at the first frame."""
        client = self._client
        if not self._markers:
            self._markers = discs(client, SHOWN, REACH, _LATER_COLOUR)
        for k, body in enumerate(self._markers):
            x, y = self.course[min(self.goal + k, len(self.course) - 1)]
            colour = _GOAL_COLOUR if k == 0 else _LATER_COLOUR
            place_disc(client, body, x, y, scene.ground.spawn_height(x, y), colour)

    def place(self, scene: Any, rng: np.random.Generator) -> None:
        """Draw the episode's course from the start stream."""
        self.course = draw_course(rng)
        self.goal = 0
        self._reached = False

    def observe(
        self, scene: Any, states: list[Any], commands: list[float], targets: list[Any], step: int
    ) -> list[np.ndarray]:
        """The bot's robot layout through the task's sensors, then its goal's and the next
        goal's distance and bearing. A goal within `REACH` m counts as reached here, once a
        step, before the step's outcome is scored."""
        state = states[0]
        course = self.course
        if self._late:
            self._scored = (self.goal, self._reached)
        distance, cos, sin = bearing(state, course[self.goal])
        self._reached = distance <= REACH and self.goal < len(course) - 1
        if self._reached:
            self.goal += 1
            distance, cos, sin = bearing(state, course[self.goal])
        after = course[min(self.goal + 1, len(course) - 1)]
        goal = (min(distance, SEEN_DISTANCE), cos, sin)
        next_distance, next_cos, next_sin = bearing(state, after)
        reading = scene.reading(state, step)
        own = (*own_values(state), *goal, min(next_distance, SEEN_DISTANCE), next_cos, next_sin)
        return [observation_with(reading, commands[0], targets[0], own)]

    def outcome(
        self, agents: list[str], states: list[Any], targets: list[float], seed: int
    ) -> Outcome:
        """The shared reward for the velocity towards the goal, whether the bot fell (which
        ends its episode), and its info: the two terms, `velocity_error` (m/s), the goal's
        `goal_distance` (m) and `waypoints_per_minute` (at a step that reached a point,
        the steps a minute holds, else 0: its mean over an episode's steps is the points
        reached per minute driven)."""
        state: SteerState = states[0]
        x, y, _ = state.axle
        goal, reached = self._scored if self._late else (self.goal, self._reached)
        gx, gy = self.course[goal]
        dx, dy = gx - x, gy - y
        distance = math.sqrt(dx * dx + dy * dy)  # correctly rounded: the same on any CPU
        vx, vy = state.velocity
        toward = (vx * dx + vy * dy) / distance if distance > 0.0 else 0.0
        velocity_error = abs(toward - targets[0])
        upright, tracking = self.reward.terms(state.pitch, velocity_error)
        fell = has_fallen(state)
        info = {
            "reward_upright": upright,
            "reward_velocity": tracking,
            "velocity_error": velocity_error,
            "goal_distance": distance,
            "waypoints_per_minute": self._per_minute if reached else 0.0,
        }
        return Outcome(
            (upright + tracking,), (fell,), fell, f"{agents[0]} fell" if fell else "", (info,)
        )


# The tasks. The target speed towards the goal: 1-2 m/s, each held 2-5 s.
_SPEEDS = PiecewiseConstantVelocity(low=1.0, high=2.0, hold=(2.0, 5.0))
_COURSE = f"""\
A course of waypoints, a new one from each episode's seed: {COURSE_POINTS} points drawn
uniformly within {COURSE_RADIUS:g} m of the start, each at least {MIN_LEG:g} m from the one
before, so that a leg may turn any way, up to turning back. The bot's goal is the first
point it has not reached; it reaches it within {REACH:g} m, and the goal moves on. It
observes its goal's and the next goal's distance and bearing (cosine and sine, + to the
left). The target speed towards the goal (observation 4) is drawn from [1, 2] m/s and
held 2-5 s at a time. The reward is the shared one (`StayUpReward`) with the velocity it
tracks taken along the direction to the goal: |velocity . unit(goal - axle) - target|."""

_FLAT = f"{_COURSE}\n\nFlat ground; sensors are perfect."
_HILLS = f"""\
{_COURSE}

The ground is a square patch of random hills, 16 x 16 m around the start (the course's
disc and room beyond it): white noise low-passed by a Gaussian of 0.2 m on 0.1 m cells,
a new one from each episode's seed, with a level pad of 0.5 m at the start and flat
ground around the patch. `difficulty` (default 0.85, any number in [0, 1]) sets the
hills' height, 0.01 m + 0.30 m x difficulty (0.265 m at the default, 2.6 wheel radii):
there the steering law finishes 20-60% of the episodes (docs/tasks.md). Sensors are perfect."""
_HILL_PATCH = HeightfieldTerrain(
    generator=Bumps(min_height=0.01, extra_height=0.30, feature_size=0.2),
    difficulty=0.85,
    size=(16.0, 16.0),
    cell_size=0.1,
    start_margin=8.0,
)
_V1 = (
    "v1: the one step protocol (`Scenario.observe_and_score`): a reached waypoint is "
    "scored, its reward and `waypoints_per_minute`, in the step that reaches it, not the "
    "step after; robot, ground, courses, commands and seeds as v0."
)

TASKS = (
    TaskSpec(
        id="bbbench/Waypoints-v0",
        summary="steer through a seeded course of waypoints on flat ground",
        description=_FLAT,
        robot="two-wheel-steer",
        scenario="waypoints",
        command=_SPEEDS,
        reward=StayUpReward(),
        random_return=0.7361418690243088,
    ),
    TaskSpec(
        id="bbbench/Waypoints-v1",
        summary="steer through a seeded course of waypoints on flat ground",
        description=_FLAT,
        robot="two-wheel-steer",
        scenario="waypoints",
        command=_SPEEDS,
        reward=StayUpReward(),
        version_history=("v0: initial release.", _V1),
        random_return=0.7361418690243088,
    ),
    TaskSpec(
        id="bbbench/WaypointsBumps-v0",
        summary="steer through a seeded course of waypoints over random hills",
        description=_HILLS,
        robot="two-wheel-steer",
        scenario="waypoints",
        command=_SPEEDS,
        reward=StayUpReward(),
        terrain=_HILL_PATCH,
        random_return=0.7306982237671567,
    ),
    TaskSpec(
        id="bbbench/WaypointsBumps-v1",
        summary="steer through a seeded course of waypoints over random hills",
        description=_HILLS,
        robot="two-wheel-steer",
        scenario="waypoints",
        command=_SPEEDS,
        reward=StayUpReward(),
        terrain=_HILL_PATCH,
        version_history=("v0: initial release.", _V1),
        random_return=0.7306982237671567,
    ),
)
