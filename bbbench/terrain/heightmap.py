"""`Heightmap` and `HeightfieldTerrain`: a generated ground placed in the world."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

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
        nx, ny = self.shape
        return (
            self.origin[0] + self.cell_size * np.arange(nx),
            self.origin[1] + self.cell_size * np.arange(ny),
        )

    def max_height_near(self, x: float, y: float, radius: float) -> float:
        """The highest node within `radius` m of (x, y) (0 off the map): where to spawn."""
        xs, ys = self.node_coordinates()
        rows = np.abs(xs - x) <= radius + self.cell_size
        cols = np.abs(ys - y) <= radius + self.cell_size
        patch = self.heights[np.ix_(rows, cols)]
        return float(patch.max()) if patch.size else 0.0


@dataclass(frozen=True)
class HeightfieldTerrain:
    """A procedural ground: a generator, its difficulty, and the strip it covers.

    The strip is `size` = (width in x, length in y) m of `cell_size` m cells;
    the bot starts at the origin, `start_margin` m from the strip's near end,
    on a level pad of radius `start_pad` m, and drives along +y. Past the strip
    the ground drops `edge_drop` m to a plane.
    """

    generator: TerrainGenerator = field(default_factory=Flat)
    difficulty: float = 0.0
    size: tuple[float, float] = (4.0, 24.0)
    cell_size: float = 0.15  # m: 0.1 m cells stepped 8-10% slower (docs/performance.md)
    start_margin: float = 3.0
    start_pad: float = 0.5
    edge_drop: float = 0.3

    def __post_init__(self) -> None:
        self.generator.height_bounds(self.difficulty)  # validates difficulty
        if not (self.cell_size > 0 and min(self.size) >= 2 * self.cell_size):
            raise ValueError(
                f"terrain needs cell_size > 0 and a size of at least two cells, got "
                f"size={self.size!r}, cell_size={self.cell_size!r}"
            )

    @property
    def grid_shape(self) -> tuple[int, int]:
        return (
            round(self.size[0] / self.cell_size) + 1,
            round(self.size[1] / self.cell_size) + 1,
        )

    @property
    def height_bounds(self) -> tuple[float, float]:
        return self.generator.height_bounds(self.difficulty)

    def generate(self, rng: np.random.Generator) -> Heightmap:
        """One episode's ground, drawn from `rng`."""
        heights = self.generator(rng, self.difficulty, self.grid_shape, self.cell_size)
        origin = (-self.size[0] / 2.0, -self.start_margin)
        heightmap = Heightmap(heights, self.cell_size, origin)
        xs, ys = heightmap.node_coordinates()
        # Level the start pad, blending into the terrain over one more pad radius.
        distance = np.hypot(xs[:, None], ys[None, :])
        blend = np.clip((distance - self.start_pad) / self.start_pad, 0.0, 1.0)
        pad_height = float(heights[distance <= self.start_pad].mean())
        leveled = pad_height + (heights - pad_height) * blend
        return Heightmap(leveled, self.cell_size, origin)
