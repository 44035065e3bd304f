"""Several bots in one world: how many, where they start, what each senses of the others.

`Group` is the part of a multi-bot task's spec that single-bot tasks lack;
`spawn_poses` draws an episode's start, and `neighbour_block` computes the
observation block about each bot's nearest neighbours, for all bots at once.
"""

from __future__ import annotations

import math
import operator

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

    @property
    def observation_size(self) -> int:
        """Values in the neighbour block: `neighbours` x (right, forward, and their rates)."""
        return self.neighbours * len(NEIGHBOUR_FIELDS)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Low and high of the neighbour block, bot by bot."""
        one = np.array([self.neighbour_range] * 2 + [NEIGHBOUR_SPEED_RANGE] * 2, dtype=np.float64)
        high = np.tile(one, self.neighbours)
        return -high, high


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


def neighbour_block(
    positions: np.ndarray,
    velocities: np.ndarray,
    headings: np.ndarray,
    group: Group,
    observers: list[int] | None = None,
) -> np.ndarray:
    """For each observing bot, its nearest other bots in its own frame, nearest first.

    Args:
        positions: (n,) horizontal positions of every bot in the world, as
            complex numbers x + iy (m): one numpy operation rotates them.
        velocities: (n,) their horizontal velocities, complex (m/s).
        headings: (n,) their forward directions, complex unit numbers.
        observers: the indices of the bots to compute the block for (default all).

    Returns an (len(observers), K * 4) array: for each of the K nearest bots
    within range, its position right of and ahead of the observer (m) and its
    velocity relative to the observer's, in the same axes (m/s); zeros where
    there are fewer. Distance ties go to the lower bot index.
    """
    n, k = len(positions), group.neighbours
    if observers is None:
        observers = range(n)
    rows = np.asarray(observers, dtype=np.intp)
    m, slots = len(rows), min(k, n - 1)
    offsets = positions - positions[rows, None]  # [r, j]: bot j seen from bot rows[r]
    distance = np.abs(offsets)
    distance[np.arange(m), rows] = np.inf  # not itself
    distance[distance > group.neighbour_range] = np.inf
    nearest = np.argsort(distance, axis=1, kind="stable")[:, :slots]
    index = np.arange(m)[:, None]
    unseen = distance[index, nearest] == np.inf
    # Multiplying by i * conj(heading) turns a world vector x + iy into the bot's
    # frame as right + i forward: viewed as floats, the block's field order.
    turn = (1j * np.conj(headings[rows]))[:, None, None]
    pairs = np.stack((offsets[index, nearest], velocities[nearest] - velocities[rows, None]), -1)
    local = (pairs * turn).view(np.float64)  # (m, slots, 4)
    local[unseen] = 0.0
    rates = local[..., 2:]
    np.minimum(rates, NEIGHBOUR_SPEED_RANGE, out=rates)
    np.maximum(rates, -NEIGHBOUR_SPEED_RANGE, out=rates)
    if slots == k:
        return local.reshape(m, k * len(NEIGHBOUR_FIELDS))
    block = np.zeros((m, k * len(NEIGHBOUR_FIELDS)))
    block[:, : slots * len(NEIGHBOUR_FIELDS)] = local.reshape(m, -1)
    return block
