"""Several bots in one world: how many, where they start, what each senses of the others.

`Group` is the part of a multi-bot task's spec that single-bot tasks lack;
`spawn_poses` draws an episode's start, and `nearest_others` finds each bot's
neighbours for its observation.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence

import numpy as np

from bbbench.parameters import parameters

MIN_BOTS, MAX_BOTS = 2, 16
NEIGHBOUR_FIELDS = ("right", "forward", "right_velocity", "forward_velocity")
# m/s: relative velocities saturate here (two bots at top speed head-on, 4.9 m/s,
# fit with room for a falling torso's swing).
NEIGHBOUR_SPEED_RANGE = 10.0


@parameters
class Group:
    """A group of bots sharing one world.

    The bots start spread around a circle of `spawn_radius` m about the
    origin, each heading for its centre give or take `heading_jitter` rad, so
    their paths cross. Each bot observes its `neighbours` nearest other bots
    within `neighbour_range` m.
    """

    n_bots: int = 4
    neighbours: int = 3  # K: the nearest bots each bot observes
    neighbour_range: float = 5.0  # m: farther bots are not observed
    spawn_radius: float = 2.5  # m
    heading_jitter: float = 0.3  # rad

    def __post_init__(self) -> None:
        try:
            n_bots = operator.index(self.n_bots)
        except TypeError:
            n_bots = None
        if n_bots is None or not MIN_BOTS <= n_bots <= MAX_BOTS:
            raise ValueError(
                f"n_bots must be a whole number from {MIN_BOTS} to {MAX_BOTS}, got {self.n_bots!r}"
            )
        if not (isinstance(self.neighbours, int) and self.neighbours >= 1):
            raise ValueError(f"neighbours must be a whole number >= 1, got {self.neighbours!r}")
        if not self.neighbour_range > 0:
            raise ValueError(f"neighbour_range must be > 0 m, got {self.neighbour_range!r}")
        # Bots start at least 0.6 m apart on the circle (their wheels span 0.24 m).
        if not 2 * math.pi * self.spawn_radius / MAX_BOTS >= 0.6:
            raise ValueError(
                f"spawn_radius {self.spawn_radius!r} m leaves no room for {MAX_BOTS} bots"
            )
        if not 0 <= self.heading_jitter < math.pi / 2:
            raise ValueError(
                f"heading_jitter must be in [0, pi/2) rad, got {self.heading_jitter!r}"
            )


def spawn_poses(rng: np.random.Generator, group: Group) -> list[tuple[tuple[float, float], float]]:
    """Each bot's start (x, y) and yaw, drawn from `rng`.

    The bots are spaced evenly around the circle, the whole pattern turned by a
    random angle and each bot moved along it by up to a quarter of the spacing;
    each heads for the centre, turned by up to `heading_jitter`. Yaw 0 faces +y.
    """
    n = group.n_bots
    spacing = 2 * math.pi / n
    turn = rng.uniform(0.0, spacing)
    shifts = rng.uniform(-spacing / 4, spacing / 4, size=n)
    jitters = rng.uniform(-group.heading_jitter, group.heading_jitter, size=n)
    poses = []
    for i in range(n):
        angle = turn + i * spacing + float(shifts[i])
        x, y = group.spawn_radius * math.cos(angle), group.spawn_radius * math.sin(angle)
        # Facing the centre: forward (-sin yaw, cos yaw) = -(cos angle, sin angle).
        yaw = angle + math.pi / 2 + float(jitters[i])
        poses.append(((x, y), yaw))
    return poses


def nearest_others(positions: list[complex], k: int) -> list[list[int]]:
    """For each bot, the indices of the (up to) `k` other bots nearest it, nearest first.

    Positions are horizontal, as complex numbers x + iy (m). Distance ties go to
    the lower index.
    """
    n = len(positions)
    points = np.array(positions, dtype=complex)
    distance = np.abs(points[None, :] - points[:, None])
    distance.flat[:: n + 1] = np.inf  # not itself
    return np.argsort(distance, axis=1, kind="stable")[:, : min(k, n - 1)].tolist()


def team_robot(robots: Sequence[str], bot: int) -> str:
    """The robot that bot `bot` of a team of `robots` plays: bot i plays robots[i %
    len(robots)], at any team size (`TaskSpec.robots`)."""
    return robots[bot % len(robots)]
