"""Seeded, pure-numpy heightmap generators.

Each generator is a frozen description with a `difficulty`-dependent height
bound and a `__call__(rng, difficulty, shape, cell_size)` that returns heights
(m) on a grid, `heights[i, j]` at x-index i and y-index j, always within
`height_bounds(difficulty)`. Generators with `periodic_x = True` also take
`periodic=True`: then row i + shape[0] would equal row i, so copies of the grid
side by side join seamlessly (terrain with no side edge). Nothing here knows
about robots or bullet.
"""

from __future__ import annotations

import numpy as np

from bbbench import portable
from bbbench.parameters import is_real, parameters


def _check_difficulty(difficulty: float) -> float:
    if not is_real(difficulty) or not 0.0 <= difficulty <= 1.0:
        raise ValueError(f"difficulty must be a number in [0, 1], got {difficulty!r}")
    return float(difficulty)


def _fast_fft_length(n: int) -> int:
    """The next multiple of 16 from n: FFTs of prime lengths are many times slower."""
    return -(-n // 16) * 16


_KERNELS: dict[tuple, np.ndarray] = {}  # (padded shape, cell size, feature size) -> kernel


def _gaussian_kernel(padded: tuple[int, int], cell_size: float, feature_size: float) -> np.ndarray:
    """The Gaussian low-pass in frequency space: the same for every episode of a terrain,
    so computed once (a tenth of a Bumps-v0 reset), and read-only."""
    key = (padded, cell_size, feature_size)
    kernel = _KERNELS.get(key)
    if kernel is None:
        fx = np.fft.fftfreq(padded[0], d=cell_size)[:, None]
        fy = np.fft.rfftfreq(padded[1], d=cell_size)[None, :]
        # e**x with the same bits on every CPU: numpy's `np.exp` rounds by SIMD path,
        # and terrain made with it differed between machines (docs/tasks.md).
        kernel = portable.exp(-2.0 * (np.pi * feature_size) ** 2 * (fx**2 + fy**2))
        kernel.flags.writeable = False
        _KERNELS[key] = kernel
    return kernel


def _smooth_noise(
    rng: np.random.Generator,
    shape: tuple[int, int],
    cell_size: float,
    feature_size: float,
    periodic_x: bool = False,
) -> np.ndarray:
    """White noise low-passed by a Gaussian of std `feature_size` m (FFT), scaled to [0, 1].

    The noise is drawn on a larger grid of FFT-friendly size and cropped, which
    also cuts off the FFT's wrap-around between opposite edges; with `periodic_x`
    it is not padded along x, where the wrap-around makes it periodic.
    """
    padded = (shape[0] if periodic_x else _fast_fft_length(shape[0]), _fast_fft_length(shape[1]))
    noise = rng.standard_normal(padded)
    kernel = _gaussian_kernel(padded, cell_size, feature_size)
    smooth = np.fft.irfft2(np.fft.rfft2(noise) * kernel, s=padded)[: shape[0], : shape[1]]
    low, high = smooth.min(), smooth.max()
    return (smooth - low) / (high - low) if high > low else np.zeros(shape)


@parameters
class Level:
    """Level ground."""

    periodic_x = True

    def height_bounds(self, difficulty: float) -> tuple[float, float]:
        _check_difficulty(difficulty)
        return (0.0, 0.0)

    def __call__(
        self,
        rng: np.random.Generator,
        difficulty: float,
        shape: tuple[int, int],
        cell_size: float,
        periodic: bool = False,
    ) -> np.ndarray:
        _check_difficulty(difficulty)
        return np.zeros(shape)


class _HeightGrowsWithDifficulty:
    """Heights from 0 up to `min_height + extra_height * difficulty` (m)."""

    min_height: float
    extra_height: float

    def max_height(self, difficulty: float) -> float:
        return self.min_height + self.extra_height * _check_difficulty(difficulty)

    def height_bounds(self, difficulty: float) -> tuple[float, float]:
        return (0.0, self.max_height(difficulty))


@parameters
class Bumps(_HeightGrowsWithDifficulty):
    """Smooth random hills: low-passed noise, as high as `max_height(difficulty)`.

    At difficulty 0 the hills are `min_height` (a fifth of the 0.1 m wheel
    radius) high; at 1, `min_height + extra_height`.
    """

    min_height: float = 0.02  # m
    extra_height: float = 0.06  # m at difficulty 1
    feature_size: float = 0.35  # m, the std of the smoothing Gaussian

    periodic_x = True

    def __call__(
        self,
        rng: np.random.Generator,
        difficulty: float,
        shape: tuple[int, int],
        cell_size: float,
        periodic: bool = False,
    ) -> np.ndarray:
        height = self.max_height(difficulty)
        return height * _smooth_noise(rng, shape, cell_size, self.feature_size, periodic)


@parameters
class Obstacles(_HeightGrowsWithDifficulty):
    """Scattered boxes and full-width steps (raised bands) on level ground.

    Obstacle heights are drawn from [0.25, 1] x `max_height(difficulty)`; their
    number grows with difficulty.
    """

    min_height: float = 0.015  # m at difficulty 0
    extra_height: float = 0.035  # m more at difficulty 1
    boxes_per_m2: float = 0.15  # at difficulty 0; twice that at 1
    steps_per_m: float = 0.1  # full-width bands per metre of length

    periodic_x = False

    def __call__(
        self, rng: np.random.Generator, difficulty: float, shape: tuple[int, int], cell_size: float
    ) -> np.ndarray:
        height = self.max_height(difficulty)
        nx, ny = shape
        heights = np.zeros(shape)
        area = nx * ny * cell_size**2
        # All draws at once, boxes then steps; only the painting loops.
        n_boxes = rng.poisson(self.boxes_per_m2 * (1.0 + difficulty) * area)
        half_sizes = (rng.uniform(0.1, 0.4, size=(n_boxes, 2)) / cell_size).astype(int) + 1
        centres = np.stack([rng.integers(0, nx, n_boxes), rng.integers(0, ny, n_boxes)], axis=1)
        box_heights = rng.uniform(0.25, 1.0, n_boxes) * height
        for (half_x, half_y), (i, j), level in zip(half_sizes, centres, box_heights, strict=True):
            box = heights[max(i - half_x, 0) : i + half_x, max(j - half_y, 0) : j + half_y]
            np.maximum(box, level, out=box)
        n_steps = rng.poisson(self.steps_per_m * ny * cell_size)
        depths = (rng.uniform(0.3, 1.5, n_steps) / cell_size).astype(int) + 1
        starts = rng.integers(0, ny, n_steps)
        step_heights = rng.uniform(0.25, 1.0, n_steps) * height
        for depth, j, level in zip(depths, starts, step_heights, strict=True):
            band = heights[:, j : j + depth]
            np.maximum(band, level, out=band)
        return heights


@parameters
class Slopes:
    """Ramps up and down along the driving direction (y), flat in x.

    Each ramp's incline is drawn up to `max_incline(difficulty)`; heights stay
    within [0, max_height].
    """

    min_incline: float = 0.05  # rad (about 3 degrees) at difficulty 0
    extra_incline: float = 0.15  # rad more at difficulty 1
    max_height: float = 0.5  # m
    ramp_length: tuple[float, float] = (1.0, 3.0)  # m

    periodic_x = True  # level across x

    def max_incline(self, difficulty: float) -> float:
        return self.min_incline + self.extra_incline * _check_difficulty(difficulty)

    def height_bounds(self, difficulty: float) -> tuple[float, float]:
        _check_difficulty(difficulty)
        return (0.0, self.max_height)

    def __call__(
        self,
        rng: np.random.Generator,
        difficulty: float,
        shape: tuple[int, int],
        cell_size: float,
        periodic: bool = False,
    ) -> np.ndarray:
        incline = self.max_incline(difficulty)
        nx, ny = shape
        profile = np.zeros(ny)
        j, level = 0, 0.0
        while j < ny:
            length = int(rng.uniform(*self.ramp_length) / cell_size) + 1
            grade = np.tan(rng.uniform(-incline, incline))
            ramp = level + grade * cell_size * np.arange(1, length + 1)
            profile[j : j + length] = np.clip(ramp, 0.0, self.max_height)[: ny - j]
            level = profile[min(j + length, ny) - 1]
            j += length
        return np.broadcast_to(profile, (nx, ny)).copy()


@parameters
class ObstacleCourse(_HeightGrowsWithDifficulty):
    """Boxes and full-width steps one after another along the driving direction (y).

    The obstacles' spacing shrinks with difficulty: each lies a gap drawn from
    `gap` m after the one before, the gap's upper end falling from
    `gap[1]` at difficulty 0 to `gap[0]` at 1, so that at difficulty 1 a bot
    meets the next obstacle before it has recovered from the last (no flat
    run-up). Each obstacle is, with probability `step_fraction`, a step: a
    full-width raised band `depth` m deep; otherwise a box `width` m across at a
    random x within `box_spread` m of the strip's middle line. Heights are drawn
    from [0.25, 1] x `max_height(difficulty)`, from `min_height` at difficulty 0
    to `min_height + extra_height` at 1.
    """

    min_height: float = 0.01  # m at difficulty 0
    extra_height: float = 0.05  # m more at difficulty 1
    gap: tuple[float, float] = (0.3, 2.0)  # m: the gap's range at difficulty 0
    step_fraction: float = 0.4  # of obstacles that span the strip's width
    depth: tuple[float, float] = (0.1, 0.8)  # m along y, steps and boxes alike
    width: tuple[float, float] = (0.3, 1.2)  # m across x, boxes
    box_spread: float = 1.0  # m: box centres lie within this of the grid's middle row

    periodic_x = True

    def max_gap(self, difficulty: float) -> float:
        """The gap's upper end (m) at `difficulty`."""
        low, high = self.gap
        return high - (high - low) * _check_difficulty(difficulty)

    def __call__(
        self,
        rng: np.random.Generator,
        difficulty: float,
        shape: tuple[int, int],
        cell_size: float,
        periodic: bool = False,
    ) -> np.ndarray:
        height = self.max_height(difficulty)
        nx, ny = shape
        length = ny * cell_size
        # Enough draws for the shortest gaps and depths to cover the strip; all at once.
        n = int(length / (self.gap[0] + self.depth[0])) + 1
        gaps = rng.uniform(self.gap[0], self.max_gap(difficulty), n)
        depths = rng.uniform(*self.depth, n)
        is_step = rng.random(n) < self.step_fraction
        widths = rng.uniform(*self.width, n)
        centres = rng.uniform(-self.box_spread, self.box_spread, n)
        levels = rng.uniform(0.25, 1.0, n) * height
        starts = np.cumsum(gaps + np.concatenate([[0.0], depths[:-1]]))
        heights = np.zeros(shape)
        middle = (nx - 1) / 2.0
        for start, depth, step, width, centre, level in zip(
            starts, depths, is_step, widths, centres, levels, strict=True
        ):
            j0, j1 = int(start / cell_size), int((start + depth) / cell_size) + 1
            if j0 >= ny:
                break
            if step:
                rows = np.arange(nx)
            else:
                rows = np.arange(
                    int(middle + (centre - width / 2.0) / cell_size),
                    int(middle + (centre + width / 2.0) / cell_size) + 1,
                )
                # Periodic: a box across the edge goes on from the other side.
                rows = rows % nx if periodic else rows[(rows >= 0) & (rows < nx)]
            heights[rows, j0:j1] = level
        return heights


GENERATORS = {
    "flat": Level,
    "bumps": Bumps,
    "obstacles": Obstacles,
    "obstacle_course": ObstacleCourse,
    "slopes": Slopes,
}
