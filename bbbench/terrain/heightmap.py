"""`Heightmap` and `HeightfieldTerrain`: a generated ground placed in the world."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from bbbench.parameters import parameters
from bbbench.terrain.generators import Bumps, Flat, Obstacles, Slopes

TerrainGenerator = Flat | Bumps | Obstacles | Slopes


@dataclass(frozen=True, eq=False)
class Heightmap:
    """Ground heights on a regular grid, in world coordinates.

    `heights[i, j]` (m) is the ground at x = x0 + i * cell_size and
    y = y0 + j * cell_size, where (x0, y0) = `origin`, the grid's first corner.
    """

    heights: np.ndarray
    cell_size: float
    origin: tuple[float, float]

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
    """

    generator: TerrainGenerator = field(default_factory=Flat)
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

    def __post_init__(self) -> None:
        self.generator.height_bounds(self.difficulty)  # validates difficulty
        if not (self.cell_size > 0 and min(self.size) >= 2 * self.cell_size):
            raise ValueError(
                f"terrain needs cell_size > 0 and a size of at least two cells, got "
                f"size={self.size!r}, cell_size={self.cell_size!r}"
            )
        if not self.start_ring >= 0:
            raise ValueError(f"start_ring must be a radius >= 0 m, got {self.start_ring!r}")
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
        heights = self.generator(rng, self.difficulty, self.grid_shape, self.cell_size)
        pad, keep, fade = self._shaping
        # Level the start pad, blending into the terrain over one more pad radius,
        # and fade to the flat ground around the strip.
        pad_height = float(heights[pad].mean())
        shaped = (pad_height + (heights - pad_height) * keep) * fade
        return Heightmap(shaped, self.cell_size, self.origin)

    @functools.cached_property
    def _shaping(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The same every episode: the start pad's nodes, how much of the drawn terrain
        each node keeps around the pad, and each node's fade to the flat surround."""
        xs, ys = _node_coordinates(self.origin, self.cell_size, self.grid_shape)
        distance = np.abs(np.hypot(xs[:, None], ys[None, :]) - self.start_ring)
        keep = np.clip((distance - self.start_pad) / self.start_pad, 0.0, 1.0)
        x_min, x_max, y_min, y_max = self.bounds
        to_edge = np.minimum(
            np.minimum(xs - x_min, x_max - xs)[:, None], np.minimum(ys - y_min, y_max - ys)[None, :]
        )
        fade = np.clip(to_edge / self.border, 0.0, 1.0)
        return distance <= self.start_pad, keep, fade
