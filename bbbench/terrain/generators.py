"""Seeded, pure-numpy heightmap generators.

Each generator is a frozen description with a `difficulty`-dependent height
bound and a `__call__(rng, difficulty, shape, cell_size)` that returns heights
(m) on a grid, `heights[i, j]` at x-index i and y-index j, always within
`height_bounds(difficulty)`. Nothing here knows about robots or bullet.
"""

from __future__ import annotations

import numpy as np

from bbbench.parameters import parameters


def _check_difficulty(difficulty: float) -> float:
    if (
        isinstance(difficulty, bool)
        or not isinstance(difficulty, int | float | np.integer | np.floating)
        or not 0.0 <= difficulty <= 1.0
    ):
        raise ValueError(f"difficulty must be a number in [0, 1], got {difficulty!r}")
    return float(difficulty)


def _fast_fft_length(n: int) -> int:
    """The next multiple of 16 from n: FFTs of prime lengths are many times slower."""
    return -(-n // 16) * 16


def _smooth_noise(
    rng: np.random.Generator, shape: tuple[int, int], cell_size: float, feature_size: float
) -> np.ndarray:
    """White noise low-passed by a Gaussian of std `feature_size` m (FFT), scaled to [0, 1].

    The noise is drawn on a larger grid of FFT-friendly size and cropped, which
    also cuts off the FFT's wrap-around between opposite edges.
    """
    padded = (_fast_fft_length(shape[0]), _fast_fft_length(shape[1]))
    noise = rng.standard_normal(padded)
    fx = np.fft.fftfreq(padded[0], d=cell_size)[:, None]
    fy = np.fft.rfftfreq(padded[1], d=cell_size)[None, :]
    kernel = np.exp(-2.0 * (np.pi * feature_size) ** 2 * (fx**2 + fy**2))
    smooth = np.fft.irfft2(np.fft.rfft2(noise) * kernel, s=padded)[: shape[0], : shape[1]]
    low, high = smooth.min(), smooth.max()
    return (smooth - low) / (high - low) if high > low else np.zeros(shape)


@parameters
class Flat:
    """Level ground."""

    def height_bounds(self, difficulty: float) -> tuple[float, float]:
        _check_difficulty(difficulty)
        return (0.0, 0.0)

    def __call__(
        self, rng: np.random.Generator, difficulty: float, shape: tuple[int, int], cell_size: float
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

    def __call__(
        self, rng: np.random.Generator, difficulty: float, shape: tuple[int, int], cell_size: float
    ) -> np.ndarray:
        height = self.max_height(difficulty)
        return height * _smooth_noise(rng, shape, cell_size, self.feature_size)


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

    def max_incline(self, difficulty: float) -> float:
        return self.min_incline + self.extra_incline * _check_difficulty(difficulty)

    def height_bounds(self, difficulty: float) -> tuple[float, float]:
        _check_difficulty(difficulty)
        return (0.0, self.max_height)

    def __call__(
        self, rng: np.random.Generator, difficulty: float, shape: tuple[int, int], cell_size: float
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


GENERATORS = {"flat": Flat, "bumps": Bumps, "obstacles": Obstacles, "slopes": Slopes}
