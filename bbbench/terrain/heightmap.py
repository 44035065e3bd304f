"""`Heightmap` and `HeightfieldTerrain`: a generated ground placed in the world."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from bbbench.parameters import parameters
from bbbench.terrain.generators import Bumps, Level, ObstacleCourse, Obstacles, Slopes

TerrainGenerator = Level | Bumps | Obstacles | ObstacleCourse | Slopes


@dataclass(frozen=True, eq=False)
class Heightmap:
    """Ground heights on a regular grid, in world coordinates.

    `heights[i, j]` (m) is the ground at x = x0 + i * cell_size and
    y = y0 + j * cell_size, where (x0, y0) = `origin`, the grid's first corner.
    With a `period` (m), the ground repeats along x with that period, beyond
    the grid too (`HeightfieldTerrain.lateral_period`).
    """

    heights: np.ndarray
    cell_size: float
    origin: tuple[float, float]
    period: float | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape

    @property
    def extent(self) -> tuple[float, float]:
        """Size in x and y, m."""
        nx, ny = self.shape
        return ((nx - 1) * self.cell_size, (ny - 1) * self.cell_size)

    @property
    def center(self) -> tuple[float, float]:
        return (
            self.origin[0] + self.extent[0] / 2.0,
            self.origin[1] + self.extent[1] / 2.0,
        )

    def node_coordinates(self) -> tuple[np.ndarray, np.ndarray]:
        """World x of every row and y of every column of `heights`."""
        return _node_coordinates(self.origin, self.cell_size, self.shape)

    def heights_along(
        self,
        x: float,
        y: float,
        direction: tuple[float, float],
        offsets: tuple[float, ...],
        relative_to: float = 0.0,
    ) -> list[float]:
        """Ground heights (m) at (x, y) + offset * direction for each offset (m), less
        `relative_to` (m): the height of the node nearest each point (so to within the
        grid's resolution), 0 off the map (the flat ground around); a periodic map goes
        on along x.

        Plain Python over a flat list: it runs every step of a height-scan task, where
        numpy's per-call cost on a few points would dominate, and the nearest node costs
        half of a bilinear blend of four (benchmarks/bench_suite.py --height-scan).
        """
        flat, columns, last_row, last_column, scale, x0, y0, period = self._lookup
        # +0.5: int() of the shifted grid coordinate is the nearest node, for u, v >= 0.
        u, v = (x - x0) * scale + 0.5, (y - y0) * scale + 0.5
        du, dv = direction[0] * scale, direction[1] * scale
        heights = []
        for offset in offsets:
            row, column = u + offset * du, v + offset * dv
            if period:
                row %= period
            if row < 0.0 or column < 0.0 or row >= last_row or column >= last_column:
                heights.append(-relative_to)
            else:
                heights.append(flat[int(row) * columns + int(column)] - relative_to)
        return heights

    @functools.cached_property
    def _lookup(self) -> tuple:
        """What `heights_along` reads, gathered once: the heights as a flat list (row-major),
        the grid's size, 1 / cell_size, the origin and the period in cells (0: none)."""
        rows, columns = self.shape
        scale = 1.0 / self.cell_size
        period = round(self.period * scale) if self.period else 0
        return (
            self.heights.ravel().tolist(),
            columns,
            rows - 0.5,  # a shifted coordinate at or past this is off the map
            columns - 0.5,
            scale,
            self.origin[0],
            self.origin[1],
            period,
        )

    def max_height_near(self, x: float, y: float, radius: float) -> float:
        """The highest node within `radius` m of (x, y) (0 off the map): where to spawn."""
        xs, ys = self.node_coordinates()
        rows = np.abs(xs - x) <= radius + self.cell_size
        cols = np.abs(ys - y) <= radius + self.cell_size
        patch = self.heights[np.ix_(rows, cols)]
        return float(patch.max()) if patch.size else 0.0


def _node_coordinates(
    origin: tuple[float, float], cell_size: float, shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    return (
        origin[0] + cell_size * np.arange(shape[0]),
        origin[1] + cell_size * np.arange(shape[1]),
    )


@parameters
class HeightfieldTerrain:
    """A procedural ground: a generator, its difficulty, and the strip it covers.

    The strip is `size` = (width in x, length in y) m of `cell_size` m cells;
    the bot starts at the origin, `start_margin` m from the strip's near end,
    on a level pad of radius `start_pad` m, and drives along +y. Around the
    strip the ground is flat at height 0, and the strip's heights fade to 0
    over its outer `border` m, so the bot can leave it anywhere.

    With `start_ring` > 0 the level pad is a ring instead: every point within
    `start_pad` m of the circle of that radius around the origin, where a
    group of bots starts (the multi-bot tasks).

    With a `lateral_period` P the terrain has no side edge: the generator draws
    one period, the strip is two copies side by side (`size[0]` = 2 P), the
    pad is a band across the strip, and in the world the field is re-centred
    under the bot by whole periods (`terrain.bullet.BulletHeightfield.follow`),
    which leaves the ground under the bot as it was.
    """

    generator: TerrainGenerator = field(default_factory=Level)
    difficulty: float = 0.0
    # m: 12 m of driving at the fastest target, 0.8 m/s, fit with room to spare. The
    # bot cannot steer and obstacles turn it: the PD baseline leaves the strip's sides
    # in some Obstacles episodes and drives on, on the flat ground around it.
    size: tuple[float, float] = (8.0, 20.0)
    # m: each node costs about 0.25 us when a new terrain replaces the old (pybullet
    # rebuilds its render mesh too), and 0.2 m cells step faster than 0.15 m.
    cell_size: float = 0.2
    start_margin: float = 3.0
    start_pad: float = 0.5
    border: float = 0.5
    start_ring: float = 0.0  # m: 0 for a disc at the origin, else a ring of this radius
    # m: with a period, the ground repeats along x (the strip is two periods wide), the
    # start pad is a level band across it, and the field is moved by whole periods to stay
    # under a bot that drifts sideways: a bot that cannot steer never leaves the terrain.
    lateral_period: float | None = None

    def __post_init__(self) -> None:
        self.generator.height_bounds(self.difficulty)  # validates difficulty
        if not (self.cell_size > 0 and min(self.size) >= 2 * self.cell_size):
            raise ValueError(
                f"terrain needs cell_size > 0 and a size of at least two cells, got "
                f"size={self.size!r}, cell_size={self.cell_size!r}"
            )
        if not self.start_ring >= 0:
            raise ValueError(f"start_ring must be a radius >= 0 m, got {self.start_ring!r}")
        if self.lateral_period is not None:
            period = self.lateral_period
            if not self.generator.periodic_x:
                raise ValueError(
                    f"{type(self.generator).__name__} terrain cannot repeat along x: "
                    f"lateral_period needs a periodic generator"
                )
            cells = period / self.cell_size
            if not (period > 0 and abs(cells - round(cells)) < 1e-9 and self.start_ring == 0):
                raise ValueError(
                    f"lateral_period must be a whole number of cells (> 0) and needs "
                    f"start_ring=0, got {period!r} with cell_size {self.cell_size!r}"
                )
            if abs(self.size[0] - 2 * period) > 1e-9:
                raise ValueError(
                    f"a periodic strip is two periods wide: size[0] must be "
                    f"{2 * period!r} m, got {self.size[0]!r}"
                )
        if not 0 < self.border <= min(self.size) / 2:
            raise ValueError(
                f"border must be in (0, {min(self.size) / 2}] m for a strip of {self.size!r} m, "
                f"got {self.border!r}"
            )

    @property
    def grid_shape(self) -> tuple[int, int]:
        return (
            round(self.size[0] / self.cell_size) + 1,
            round(self.size[1] / self.cell_size) + 1,
        )

    @property
    def origin(self) -> tuple[float, float]:
        """The strip's first corner (x, y), m."""
        return (-self.size[0] / 2.0, -self.start_margin)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """The strip's (x min, x max, y min, y max), m; flat ground lies beyond."""
        nx, ny = self.grid_shape
        x0, y0 = self.origin
        return (x0, x0 + (nx - 1) * self.cell_size, y0, y0 + (ny - 1) * self.cell_size)

    @property
    def height_bounds(self) -> tuple[float, float]:
        return self.generator.height_bounds(self.difficulty)

    def generate(self, rng: np.random.Generator) -> Heightmap:
        """One episode's ground, drawn from `rng`."""
        if self.lateral_period is None:
            heights = self.generator(rng, self.difficulty, self.grid_shape, self.cell_size)
        else:  # one period, then two copies side by side and the first row again
            period = self.grid_shape[0] // 2
            one = self.generator(
                rng, self.difficulty, (period, self.grid_shape[1]), self.cell_size, periodic=True
            )
            heights = np.concatenate([one, one, one[:1]])
        pad, keep, fade = self._shaping
        # Level the start pad, blending into the terrain over one more pad radius,
        # and fade to the flat ground around the strip.
        pad_height = float(heights[pad].mean())
        shaped = (pad_height + (heights - pad_height) * keep) * fade
        return Heightmap(shaped, self.cell_size, self.origin, self.lateral_period)

    @functools.cached_property
    def _shaping(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The same every episode: the start pad's nodes, how much of the drawn terrain
        each node keeps around the pad, and each node's fade to the flat surround."""
        xs, ys = _node_coordinates(self.origin, self.cell_size, self.grid_shape)
        x_min, x_max, y_min, y_max = self.bounds
        if self.lateral_period is None:
            distance = np.abs(np.hypot(xs[:, None], ys[None, :]) - self.start_ring)
            to_x_edge = np.minimum(xs - x_min, x_max - xs)
        else:  # a band across the strip, and no side edge to fade to
            distance = np.broadcast_to(np.abs(ys)[None, :], self.grid_shape)
            to_x_edge = np.full(xs.shape, np.inf)
        keep = np.clip((distance - self.start_pad) / self.start_pad, 0.0, 1.0)
        to_edge = np.minimum(to_x_edge[:, None], np.minimum(ys - y_min, y_max - ys)[None, :])
        fade = np.clip(to_edge / self.border, 0.0, 1.0)
        return distance <= self.start_pad, keep, fade
