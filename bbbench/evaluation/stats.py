"""Aggregate scores as rliable does: IQM and stratified-bootstrap confidence intervals.

Implemented here with numpy and a fixed seed (rliable resamples with numpy's
global generator, and its pinned dependencies break on pandas 3). The method
is rliable's `get_interval_estimates`: resample each task's episodes with
replacement, independently per task (the strata), compute the statistic on
the resampled scores, and take the 2.5th and 97.5th percentiles over
resamples. Each interval uses a fresh generator with the same seed, so a task's
interval depends on its own scores only, not on which other tasks ran.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

BOOTSTRAP_SEED = 0
BOOTSTRAP_REPS = 10_000  # rliable's default is 50,000; 10,000 moves the bounds by < 1%
CONFIDENCE = 0.95
_CHUNK = 2_000  # resamples per batch: bounds memory on long runs


def iqm(scores: np.ndarray, axis: int = -1) -> np.ndarray | float:
    """Interquartile mean: the mean of the middle half (scipy's trim_mean(x, 0.25))."""
    scores = np.sort(np.asarray(scores, dtype=np.float64), axis=axis)
    n = scores.shape[axis]
    cut = int(0.25 * n)
    middle = np.take(scores, np.arange(cut, n - cut), axis=axis)
    result = middle.mean(axis=axis)
    return float(result) if np.ndim(result) == 0 else result


def mean(scores: np.ndarray, axis: int = -1) -> np.ndarray | float:
    result = np.asarray(scores, dtype=np.float64).mean(axis=axis)
    return float(result) if np.ndim(result) == 0 else result


def stratified_bootstrap_ci(
    strata: Sequence[np.ndarray],
    statistic: Callable[..., np.ndarray | float],
    reps: int = BOOTSTRAP_REPS,
    confidence: float = CONFIDENCE,
    seed: int = BOOTSTRAP_SEED,
) -> tuple[float, float]:
    """The percentile interval of `statistic` over the pooled scores of all strata.

    `statistic(x, axis=-1)` reduces the last axis. Each stratum (a task's
    episodes) is resampled with replacement keeping its size.
    """
    strata = [np.asarray(s, dtype=np.float64).ravel() for s in strata]
    if not strata or any(s.size == 0 for s in strata):
        raise ValueError("every stratum needs at least one score")
    if reps < 1 or not 0.0 < confidence < 1.0:
        raise ValueError(f"reps >= 1 and 0 < confidence < 1 required, got {reps}, {confidence}")
    rng = np.random.default_rng(seed)
    values = []
    for start in range(0, reps, _CHUNK):
        count = min(_CHUNK, reps - start)
        pooled = np.concatenate(
            [s[rng.integers(s.size, size=(count, s.size))] for s in strata], axis=1
        )
        values.append(statistic(pooled, axis=-1))
    tail = (1.0 - confidence) / 2.0
    low, high = np.quantile(np.concatenate(values), [tail, 1.0 - tail])
    return float(low), float(high)


def probability_of_improvement(x_strata: Sequence[np.ndarray], y_strata: Sequence[np.ndarray]):
    """rliable's P(X > Y): per task (stratum), the probability that an episode of X scores
    above an episode of Y, ties counting half (the Mann-Whitney U over n * m); averaged
    over tasks. Returns the point estimate and its stratified-bootstrap interval, X's and
    Y's episodes resampled independently (rliable's `StratifiedIndependentBootstrap`)."""
    if len(x_strata) != len(y_strata) or not x_strata:
        raise ValueError("X and Y need scores on the same, non-empty list of tasks")
    comparisons = [_wins(x, y) for x, y in zip(x_strata, y_strata, strict=True)]
    point = float(np.mean([c.mean() for c in comparisons]))
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    values = np.zeros(BOOTSTRAP_REPS)
    for wins in comparisons:
        n, m = wins.shape
        # How often each episode is drawn in each resample: then P of a resample is a
        # weighted mean of the comparison matrix, one matrix product for all resamples.
        x_counts = _draw_counts(rng, n, BOOTSTRAP_REPS)
        y_counts = _draw_counts(rng, m, BOOTSTRAP_REPS)
        values += np.einsum("rn,rn->r", x_counts @ wins, y_counts) / (n * m)
    values /= len(comparisons)
    tail = (1.0 - CONFIDENCE) / 2.0
    low, high = np.quantile(values, [tail, 1.0 - tail])
    return point, (float(low), float(high))


def _wins(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """S[i, j] = 1 if x_i > y_j, 0.5 if equal, 0 if less."""
    x = np.asarray(x, dtype=np.float64).ravel()[:, None]
    y = np.asarray(y, dtype=np.float64).ravel()[None, :]
    if x.size == 0 or y.size == 0:
        raise ValueError("every stratum needs at least one score")
    return (x > y) + 0.5 * (x == y)


def _draw_counts(rng: np.random.Generator, size: int, reps: int) -> np.ndarray:
    """(reps, size): how many times each of `size` items is drawn, `size` draws with
    replacement per resample."""
    draws = rng.integers(size, size=(reps, size)) + size * np.arange(reps)[:, None]
    return np.bincount(draws.ravel(), minlength=reps * size).reshape(reps, size).astype(float)
